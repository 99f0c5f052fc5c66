// constants.h: the mathematical constants the kernels share (one definition, in double;
// float kernels convert at their use).
#pragma once

namespace airlight {

constexpr double kPi = 3.14159265358979323846;
constexpr double kHalfPi = 1.57079632679489661923;
constexpr double kQuarterPi = 0.78539816339744830962;
constexpr double kInv4Pi = 0.0795774715459476678844;  // 1 / (4 pi)
constexpr double kSqrtPi = 1.77245385090551602729;  // the rounded sqrt(pi), not std::sqrt(kPi)
constexpr double kTwoOverSqrtPi = 1.12837916709551257390;  // 2 / sqrt(pi), erf's derivative at 0

}  // namespace airlight
