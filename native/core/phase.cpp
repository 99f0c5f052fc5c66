// phase.cpp: phase functions (conventions in phase.h).
#include "core/phase.h"

#include <algorithm>
#include <stdexcept>

namespace airlight {

double PhaseFunction::eval(double mu) const {
    mu = std::clamp(mu, -1.0, 1.0);
    switch (kind) {
        case PhaseKind::Isotropic:
            return kInv4Pi;
        case PhaseKind::HenyeyGreenstein:
            return phase_hg(mu, g);
        case PhaseKind::Rayleigh:
            return 3.0 * kInv4Pi / 4.0 * (1.0 + mu * mu);
        case PhaseKind::HazyMie: {
            const double s = 0.5 * (1.0 + mu), s2 = s * s, s4 = s2 * s2;
            return kInv4Pi / 2.0 * (1.0 + 9.0 * s4 * s4);
        }
        case PhaseKind::MurkyMie: {
            const double s = 0.5 * (1.0 + mu), s2 = s * s, s4 = s2 * s2, s8 = s4 * s4, s16 = s8 * s8;
            return 33.0 * kInv4Pi / 83.0 * (1.0 + 50.0 * s16 * s16);
        }
    }
    return 0.0;
}

double PhaseFunction::eval_half_angle(double s2, double c2) const {
    if (kind != PhaseKind::HenyeyGreenstein) return eval(c2 - s2);
    const double denom = g >= 0.0 ? (1.0 - g) * (1.0 - g) + 4.0 * g * s2 : (1.0 + g) * (1.0 + g) - 4.0 * g * c2;
    return kInv4Pi * (1.0 - g * g) / (denom * std::sqrt(denom));
}

double PhaseFunction::lobe_width() const {
    if (kind == PhaseKind::HenyeyGreenstein) return std::max(1.0 - std::abs(g), 1e-3);
    if (kind == PhaseKind::MurkyMie) return 0.25;  // cos^64(theta/2): width ~ 1/4 rad
    return 1.0;
}

const char* phase_name(PhaseKind kind) {
    switch (kind) {
        case PhaseKind::Isotropic: return "isotropic";
        case PhaseKind::HenyeyGreenstein: return "hg";
        case PhaseKind::Rayleigh: return "rayleigh";
        case PhaseKind::HazyMie: return "hazy_mie";
        case PhaseKind::MurkyMie: return "murky_mie";
    }
    return "?";
}

PhaseFunction phase_from_name(const std::string& name, double g) {
    PhaseFunction p;
    if (name == "isotropic") p.kind = PhaseKind::Isotropic;
    else if (name == "hg" || name == "henyey_greenstein") p.kind = PhaseKind::HenyeyGreenstein;
    else if (name == "rayleigh") p.kind = PhaseKind::Rayleigh;
    else if (name == "hazy_mie") p.kind = PhaseKind::HazyMie;
    else if (name == "murky_mie") p.kind = PhaseKind::MurkyMie;
    else
        throw std::invalid_argument("unknown phase function '" + name +
                                    "'; valid: 'isotropic', 'hg', 'rayleigh', 'hazy_mie', 'murky_mie'");
    if (!(std::abs(g) < 1.0))
        throw std::invalid_argument("phase: g must be finite with |g| < 1, got " + std::to_string(g));
    if (p.kind == PhaseKind::HenyeyGreenstein) p.g = g;
    return p;
}

}  // namespace airlight
