// registry.cpp: the fog models (names are the Python-facing identifiers).
#include "models/registry.h"

#include <stdexcept>

namespace airlight {

const std::vector<ModelEntry>& model_registry() {
    static const std::vector<ModelEntry> registry{
        sun05_table_entry(), sun05_exact_entry(), quadrature_entry(), biri06_entry(),
        baseline_entry(),    hoffman02_entry(),   pegoraro10_entry(),
    };
    return registry;
}

const ModelEntry& model_entry(ModelId id) {
    for (const ModelEntry& entry : model_registry())
        if (entry.id == id) return entry;
    throw std::invalid_argument("the bake does not dispatch this model (see models())");
}

ModelId model_from_name(const std::string& name) {
    std::string valid;
    for (const ModelEntry& entry : model_registry()) {
        if (entry.name == name) return entry.id;
        valid += (valid.empty() ? "" : ", ") + ("'" + entry.name + "'");
    }
    throw std::invalid_argument("unknown model '" + name + "'; valid models: " + valid);
}

}  // namespace airlight
