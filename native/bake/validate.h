// validate.h: the bake's checks of a scene and its settings, before any work starts.
#pragma once

#include "bake/bake.h"

namespace airlight {

// Throws std::invalid_argument with a clear message (what is wrong and what to change) on
// NaN or out-of-range input: the generic checks, then the model's own (models/registry.h).
// The camera matrices are checked by CameraRays.
void validate(const SceneDescription& scene, const BakeSettings& settings);

}  // namespace airlight
