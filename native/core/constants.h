// constants.h: the mathematical constants the kernels share (one definition, in double;
// float kernels convert at their use).
#pragma once

namespace airlight {

constexpr double kPi = 3.14159265358979323846;
constexpr double kHalfPi = 1.57079632679489661923;

}  // namespace airlight
