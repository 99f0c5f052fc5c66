// model_id.h: the fog models' ids (their names, papers and implementations: registry.h).
#pragma once

namespace airlight {

enum class ModelId {
    Sun05Table,   // Sun 2005 airlight, F from the table (default, fast)
    Sun05Exact,   // Sun 2005 airlight, exact F (slower)
    Quadrature,   // adaptive quadrature of the single-scattering integral (reference, slow)
    Biri06,       // Biri 2006 Gamma table, any phase function (biri06.h)
    Hoffman02,    // Hoffman & Preetham 2002 sun fog (hoffman02.h)
    Baseline,     // constant-colour fog, what Blender's Mist pass does (baseline_fog.h)
    Pegoraro10,   // Pegoraro 2010 closed form, polynomial phase / spot profile (pegoraro10.h)
};

}  // namespace airlight
