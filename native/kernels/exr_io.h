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

// Writes one multilayer half/float EXR with channels "<layer_prefix><name>.R/G/B".
// Throws std::runtime_error with OIIO's message on failure.
void write_multilayer_exr(const std::string& path, int width, int height,
                          const std::vector<ExrPass>& passes,
                          const std::string& layer_prefix = "");

}  // namespace airlight
