// models.h: the registry of fog models. Each model turns a scene description and the
// per-sample ray data into airlight; later models (anisotropic phase, spot/sun lights,
// surface shading, Gaussian media) register here and the bake dispatches by id.
#pragma once

#include <string>
#include <vector>

namespace airlight {

enum class ModelId {
    Sun05Table,   // Sun 2005 airlight, F from the table (default, fast)
    Sun05Exact,   // Sun 2005 airlight, exact F (slower)
    Quadrature,   // adaptive quadrature of eq. 5 (reference, slow)
    Biri06,       // Biri 2006 Gamma table, any phase function (biri06.h)
    Hoffman02,    // Hoffman & Preetham 2002 sun fog (hoffman02.h)
    Baseline,     // constant-colour fog, what Blender's Mist pass does (baseline_fog.h)
    Pegoraro10,   // Pegoraro 2010 closed form, polynomial phase / spot profile (pegoraro10.h)
};

struct ModelInfo {
    ModelId id;
    std::string name;         // identifier used from Python, e.g. "sun05"
    std::string description;  // one line for UI tooltips
};

const std::vector<ModelInfo>& model_registry();
// Kernels with tests and bindings that the bake does not dispatch yet (bake.cpp would
// return 0 for them); they move into model_registry() when the bake handles them.
const std::vector<ModelInfo>& kernel_models_pending_bake();
// Throws std::invalid_argument listing the valid names if _name_ is unknown.
ModelId model_from_name(const std::string& name);

}  // namespace airlight
