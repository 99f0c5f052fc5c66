// models.cpp: the registry of fog models (names are the Python-facing identifiers).
#include "models.h"

#include <stdexcept>

namespace airlight {

const std::vector<ModelInfo>& model_registry() {
    static const std::vector<ModelInfo> registry{
        {ModelId::Sun05Table, "sun05", "Sun et al. 2005 airlight with the tabulated F (fast, default)"},
        {ModelId::Sun05Exact, "sun05_exact", "Sun et al. 2005 airlight with the exact F (slower reference)"},
        {ModelId::Quadrature, "quadrature", "Adaptive quadrature of the single-scattering integral (slow reference)"},
    };
    return registry;
}

ModelId model_from_name(const std::string& name) {
    std::string valid;
    for (const ModelInfo& info : model_registry()) {
        if (info.name == name) return info.id;
        valid += (valid.empty() ? "" : ", ") + ("'" + info.name + "'");
    }
    throw std::invalid_argument("unknown model '" + name + "'; valid models: " + valid);
}

}  // namespace airlight
