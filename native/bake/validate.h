// validate.h: the bake's checks of a scene and its settings, before any work starts.
#pragma once

#include "bake/bake.h"

namespace airlight {

// Throws std::invalid_argument with a clear message (what is wrong and what to change) on
// NaN or out-of-range input: the generic checks, then the model's own (models/registry.h).
// The camera matrices are checked by CameraRays.
// Last, it refuses a bake whose images (bake_image_bytes) exceed the memory available
// (core/memory.h), before any of them is allocated.
void validate(const SceneDescription& scene, const BakeSettings& settings);

// Bytes of the images a bake allocates: per pixel the depth, the edge key, the airlight and
// the transmittance (8 floats) and one float of scratch (measured: 8.6 floats a pixel at
// 1000 x 1000); with surface shading 3 floats per light (point, spot and sun), the glow and
// the normals (6), and the gloss glow (3) with a Phong exponent.
double bake_image_bytes(const SceneDescription& scene, const BakeSettings& settings);

}  // namespace airlight
