// preview_factors.cpp: the viewport preview's per-edit factors (preview_factors.h). The
// other Gaussians' share of each T comes from gaussian_depths_to_centres (float,
// fast_erf.h: ~1e-5 relative per Gaussian), Gaussian i's own half exactly (double).
#include "gaussian/preview_factors.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "gaussian/centre_depths.h"

namespace airlight {

namespace {

bool finite(const Vec3& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

// Throws std::invalid_argument unless the points are finite and _previous_ fits the form asked
// for (rbf_preview_factors).
void check_inputs(const Vec3& eye, const std::vector<Vec3>& lights, std::size_t n,
                  const GaussianPreviewFactors* previous, std::size_t first_new, bool eye_only) {
    if (!finite(eye)) throw std::invalid_argument("rbf_preview_factors: eye is not finite");
    for (const Vec3& s : lights)
        if (!finite(s)) throw std::invalid_argument("rbf_preview_factors: a light position is not finite");
    const std::size_t m = lights.size();
    if (eye_only) {
        if (!previous) throw std::invalid_argument("rbf_preview_factors: eye_only needs the previous factors");
        if (previous->T_sb.size() != m * n || previous->own_sb.size() != m * n) {
            std::ostringstream os;
            os << "rbf_preview_factors: eye_only: previous factors must hold the light rows of all " << n
               << " Gaussians and the same " << m << " lights";
            throw std::invalid_argument(os.str());
        }
    }
    const std::size_t n_old = previous ? first_new : 0;
    if (previous && !eye_only) {
        if (first_new > n || previous->T_vb.size() != n_old || previous->own_vb.size() != n_old ||
            previous->T_sb.size() != m * n_old || previous->own_sb.size() != m * n_old) {
            std::ostringstream os;
            os << "rbf_preview_factors: previous factors must describe the first first_new = " << first_new
               << " Gaussians and the same " << m << " lights";
            throw std::invalid_argument(os.str());
        }
    }
}

// Gaussian i's own share T_i(from, b_i) and the whole T(from, b_i) given the others' share.
void own_and_total(const GaussianMedium& medium, std::size_t i, const Vec3& from, double others, double& T,
                   double& own_out) {
    const Vec3 d = medium.centre(i) - from;
    const double D = glm::length(d);
    const double own = D > 0.0 ? medium.gaussian_optical_depth(i, from, d / D, 0.0, D) : 0.0;
    T = others + (D > 0.0 ? background_depth(medium.beta0(), D) : 0.0) + own;
    own_out = own;
}

}  // namespace

GaussianPreviewFactors rbf_preview_factors(const GaussianMedium& medium, const Vec3& eye,
                                           const std::vector<Vec3>& lights, int threads,
                                           const GaussianPreviewFactors* previous, std::size_t first_new,
                                           bool eye_only) {
    const std::size_t n = medium.size(), m = lights.size();
    check_inputs(eye, lights, n, previous, first_new, eye_only);
    const std::size_t n_old = previous ? first_new : 0;
    GaussianPreviewFactors f;
    f.T_vb.resize(n);
    f.own_vb.resize(n);
    f.T_sb.resize(m * n);
    f.own_sb.resize(m * n);
    f.radius.resize(n);
    for (std::size_t i = 0; i < n; ++i) f.radius[i] = medium.cull_radius(i);
    for (const Vec3& s : lights) {
        const Vec3 d = eye - s;
        const double D = glm::length(d);
        f.Dsv.push_back(D);
        f.Csv.push_back(D > 0.0 ? std::exp(-medium.optical_depth_ray(s, d / D, D, GaussianMedium::npos, false)) : 1.0);
    }
    if (eye_only) {
        // The eye row as in the full call (the same star, row 0 alone); the light rows
        // do not depend on the eye.
        const std::vector<double> others = gaussian_depths_to_centres(medium, {eye}, 0, n, 0, n, threads);
        for (std::size_t i = 0; i < n; ++i) own_and_total(medium, i, eye, others[i], f.T_vb[i], f.own_vb[i]);
        f.T_sb = previous->T_sb;
        f.own_sb = previous->own_sb;
        return f;
    }
    const std::size_t rows = m + 1;  // row 0: the eye; rows 1..m: the lights
    auto T_at = [&](std::size_t row, std::size_t i) -> double& {
        return row == 0 ? f.T_vb[i] : f.T_sb[(row - 1) * n + i];
    };
    auto own_at = [&](std::size_t row, std::size_t i) -> double& {
        return row == 0 ? f.own_vb[i] : f.own_sb[(row - 1) * n + i];
    };
    // Gaussians [n_old, n): everything.
    const std::size_t n_new = n - n_old;
    std::vector<Vec3> src{eye};
    src.insert(src.end(), lights.begin(), lights.end());
    const std::vector<double> others = gaussian_depths_to_centres(medium, src, n_old, n, 0, n, threads);
    for (std::size_t row = 0; row < rows; ++row)
        for (std::size_t k = 0; k < n_new; ++k) {
            const std::size_t i = n_old + k;
            own_and_total(medium, i, src[row], others[row * n_new + k], T_at(row, i), own_at(row, i));
        }
    if (n_old == 0) return f;
    // Gaussians [0, n_old): the previous factors plus the new Gaussians' line integrals
    // (T is a sum over Gaussians), with the same culling as the full computation.
    const std::vector<double> add = gaussian_depths_to_centres(medium, src, 0, n_old, n_old, n, threads);
    for (std::size_t row = 0; row < rows; ++row)
        for (std::size_t i = 0; i < n_old; ++i) {
            const double prev_T = row == 0 ? previous->T_vb[i] : previous->T_sb[(row - 1) * n_old + i];
            const double prev_own = row == 0 ? previous->own_vb[i] : previous->own_sb[(row - 1) * n_old + i];
            T_at(row, i) = prev_T + add[row * n_old + i];
            own_at(row, i) = prev_own;
        }
    return f;
}

}  // namespace airlight
