// exr_io.h: multilayer OpenEXR output through OpenImageIO.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace airlight {

struct ExrPass {
    std::string name;           // e.g. "Airlight" -> channels "<prefix>Airlight.R/G/B"
    const float* rgb = nullptr; // width*height*3 floats, top row first
};

// Writes one multilayer EXR with channels "<layer_prefix><name>.R/G/B", stored as 32-bit
// floats, or with _half_ as 16-bit ones (OpenEXR's half: rounding to nearest, relative
// error <= 2^-11 for |x| >= 6.1e-5, absolute 3e-8 below; a quarter to a third of the
// file). _compression_: an OpenEXR compression OIIO knows ("none", "zip", "zips", "piz",
// "rle", "dwaa", "b44", ...) or "auto": PIZ for floats, ZIP at zlib's level 1 for halves,
// chosen by benchmarks/bench_exr.py (float passes hold noise in their low bits: PIZ writes
// them ~1.6x faster than ZIP at about the same size; halves ZIP at level 1 to half of PIZ's
// size in less time). The rows are interleaved and written in strips, OpenEXR compressing
// on every hardware thread. Throws std::runtime_error with OIIO's message on failure,
// std::invalid_argument on an unknown compression.
void write_multilayer_exr(const std::string& path, int width, int height,
                          const std::vector<ExrPass>& passes,
                          const std::string& layer_prefix = "", bool half = false,
                          const std::string& compression = "auto");

}  // namespace airlight
