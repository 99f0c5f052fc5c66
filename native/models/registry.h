// registry.h: the fog models, in one place (registry.cpp). Each is implemented in its own
// file, models/<paper>_model.cpp; adding a model adds its file and a line here and there.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "bake/bake.h"
#include "core/scene.h"
#include "models/fog_model.h"
#include "models/model_id.h"

namespace airlight {

struct ModelEntry {
    ModelId id;
    std::string name;         // identifier used from Python, e.g. "sun05"
    std::string description;  // one line for UI tooltips
    // The model's own checks of a scene (phases, lights, fog objects it cannot take), after
    // the bake's generic ones; throws std::invalid_argument saying what to change. May be null.
    void (*validate)(const SceneDescription& scene, const BakeSettings& settings) = nullptr;
    // Its evaluator for the bake's passes; null for models that bake the whole image
    // themselves (_bake_).
    std::unique_ptr<FogModel> (*make)(const SceneDescription& scene, const BakeSettings& settings) = nullptr;
    BakeResult (*bake)(const SceneDescription& scene, const BakeSettings& settings,
                       const ProgressFn& progress) = nullptr;
};
using ModelInfo = ModelEntry;

const std::vector<ModelEntry>& model_registry();
const ModelEntry& model_entry(ModelId id);
// Throws std::invalid_argument listing the valid names if _name_ is unknown.
ModelId model_from_name(const std::string& name);

// The models' entries (each defined beside its implementation).
ModelEntry sun05_table_entry();
ModelEntry sun05_exact_entry();
ModelEntry quadrature_entry();
ModelEntry biri06_entry();
ModelEntry baseline_entry();
ModelEntry hoffman02_entry();
ModelEntry pegoraro10_entry();

}  // namespace airlight
