// splat.cpp: GaussianSplat's set-up (Fogshop's per-(light, Gaussian) precomputation) and its
// evaluation of one Gaussian's terms on many rays, ray-major (splat_gaussian: one SIMD lane
// per ray) or Gaussian-major (lattice_batch: one lane per Gaussian), with the float kernels
// of splat_kernels.h; the homogeneous medium's term per light. Where the rays come from:
// splat_bin.cpp (the tiles' lists), splat_tile.cpp (a tile's pixels, edge rays),
// splat_reduced.cpp and splat_far_field.cpp (half and quarter resolution).
#include "gaussian/splat.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "core/constants.h"
#include "gaussian/centre_depths.h"
#include "gaussian/splat_kernels.h"
#include "homogeneous/sun05.h"
#include "homogeneous/sunlight_layer.h"
#include "homogeneous/sun05_batch.h"

namespace airlight {

using namespace splat;

namespace {

// Throws std::invalid_argument unless the extensions fit the L point lights (GaussianSplatLights).
void check_extra(const GaussianSplatLights& extra, std::size_t L) {
    const std::size_t S = extra.sun_w.size();
    if ((!extra.spot.empty() && (extra.spot.size() != L || extra.cone.size() != L)) ||
        (!extra.custom_background.empty() && extra.custom_background.size() != L) || extra.sun_E.size() != S)
        throw std::invalid_argument("GaussianSplat: spot, cone and custom_background need one entry per point light, "
                                    "sun_E one per sun");
    for (const Vec3& w : extra.sun_w)
        if (!std::isfinite(w.x) || !std::isfinite(w.y) || !std::isfinite(w.z) || std::abs(glm::length(w) - 1.0) > 1e-6)
            throw std::invalid_argument("GaussianSplat: sun directions must be finite unit vectors");
    const bool any_custom = std::find(extra.custom_background.begin(), extra.custom_background.end(), 1) !=
                            extra.custom_background.end();
    if ((S > 0 || any_custom) && !extra.background)
        throw std::invalid_argument("GaussianSplat: suns and custom backgrounds need a background function");
    if (!phase_is_isotropic(extra.phase) && !any_custom && L > 0)
        throw std::invalid_argument("GaussianSplat: a non-isotropic phase needs a custom background for every light");
}

}  // namespace

void validate_noise(const GaussianNoise& noise) {
    if (!std::isfinite(noise.amplitude) || noise.amplitude < 0.0) {
        std::ostringstream os;
        os << "noise amplitude must be finite and >= 0, got " << noise.amplitude;
        throw std::invalid_argument(os.str());
    }
    if (!std::isfinite(noise.scale) || !(noise.scale > 0.0)) {
        std::ostringstream os;
        os << "noise scale must be finite and > 0 (m), got " << noise.scale;
        throw std::invalid_argument(os.str());
    }
    if (!std::isfinite(noise.offset.x) || !std::isfinite(noise.offset.y) || !std::isfinite(noise.offset.z))
        throw std::invalid_argument("noise offset must be finite");
}

GaussianSplat::GaussianSplat(const GaussianMedium& medium, const Vec3& eye, const std::vector<Vec3>& lights,
                             const std::vector<RGB>& I0, const RGB& medium_albedo, const std::vector<double>& albedo,
                             const SpecialFTable* table, const GaussianNoise& noise, int threads,
                             const GaussianSplatLights* extra)
    : medium_(medium),
      table_(table),
      eye_(eye),
      lights_(lights),
      I0_(I0),
      medium_albedo_(medium_albedo),
      noise_(noise),
      threads_(threads) {
    validate_noise(noise);
    const std::size_t n = medium.size(), L = lights.size();
    if (I0.size() != L) throw std::invalid_argument("GaussianSplat: one I0 per light expected");
    if (!albedo.empty() && albedo.size() != 3 * n) {
        std::ostringstream os;
        os << "gaussians: albedo has " << albedo.size() << " values, expected 3 per Gaussian (" << 3 * n << ")";
        throw std::invalid_argument(os.str());
    }
    for (double x : albedo)
        if (!std::isfinite(x) || x < 0.0) throw std::invalid_argument("gaussians: albedo must be finite and >= 0");
    albedo_.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) albedo_[3 * i + c] = albedo.empty() ? medium_albedo[c] : albedo[3 * i + c];
    for (std::size_t l = 0; l < L; ++l) weight0_.push_back(medium_albedo * I0[l]);
    eye_f_[0] = float(eye.x);
    eye_f_[1] = float(eye.y);
    eye_f_[2] = float(eye.z);
    // C_sv and D_sv per light (exact, a few rays); f1 with Gaussian i's own terms removed,
    // exp(-T(s, b_i) - T(v, b_i)) without i, in float (fast_erf.h).
    for (const Vec3& s : lights) {
        const Vec3 d = eye - s;
        const double D = glm::length(d);
        Dsv_.push_back(D);
        Csv_.push_back(D > 0.0 ? std::exp(-medium.optical_depth_ray(s, d / D, D, GaussianMedium::npos, false)) : 1.0);
    }
    const std::size_t S = extra ? extra->sun_w.size() : 0;
    if (extra) {
        check_extra(*extra, L);
        extra_ = *extra;
        plain_ = phase_is_isotropic(extra->phase) && S == 0 &&
                 std::find(extra->spot.begin(), extra->spot.end(), 1) == extra->spot.end();
    }
    const std::vector<double> depth =
        L + S > 0 ? gaussian_centre_depths(medium, eye, lights, threads) : std::vector<double>();
    g_.resize(n);
    gl_.resize(n * L);
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3 rel = medium.centre(i) - eye;
        const double a = medium.scale(i), c = medium.amplitude(i);
        const double dist = glm::length(rel);
        GaussF& g = g_[i];
        g.rx = float(rel.x);
        g.ry = float(rel.y);
        g.rz = float(rel.z);
        g.a = float(a);
        g.a2 = float(a * a);
        g.k0 = float(c * kSqrtPi / (2.0 * a));
        g.ke = float(c * kSqrtPi / (2.0 * a) * std::exp(-a * a * dist * dist));
        g.nscale = dist > 0.0 ? float(noise.amplitude * medium.cull_radius(i) / dist) : 0.0f;
        g.near = false;
        g.dist = dist;
        g.radius = medium.cull_radius(i);
        for (std::size_t l = 0; l < L; ++l) {
            const Vec3 bs = medium.centre(i) - lights[l];
            const double f1 = std::exp(-depth[i] - depth[(l + 1) * n + i]) * kInv4Pi;
            GaussLightF& q = gl_[i * L + l];
            q.sx = float(bs.x);
            q.sy = float(bs.y);
            q.sz = float(bs.z);
            q.wr = float(albedo_[3 * i] * I0[l].x * f1);
            q.wg = float(albedo_[3 * i + 1] * I0[l].y * f1);
            q.wb = float(albedo_[3 * i + 2] * I0[l].z * f1);
            q.ke = float(c * kSqrtPi / (2.0 * a) * std::exp(-a * a * glm::dot(bs, bs)));
        }
    }
    for (std::size_t l = 0; l < L; ++l) {
        const Vec3 vs = eye - lights[l];
        lf_.push_back({float(vs.x), float(vs.y), float(vs.z)});
        if (extra && !extra->spot.empty() && extra->spot[l]) {
            const SpotCone& c = extra->cone[l];
            lf_[l].ax = float(c.axis.x);
            lf_[l].ay = float(c.axis.y);
            lf_[l].az = float(c.axis.z);
            lf_[l].cos_half = float(c.cos_half_angle);
            lf_[l].smooth = float(c.smooth);
            lf_[l].spread_a = float(c.spread_a);
            lf_[l].spread_b = float(c.spread_b);
        }
    }
    sun_weights(depth);
}

// Suns: f1 = exp(-T_sun(b_i) - T(v, b_i)) without Gaussian i (culled half-line depths in
// float, gaussian_sun_depths) and C = the Gaussians' transmittance from the eye towards the
// sun; _depth_: T(v, b_i) without i in its first row (gaussian_centre_depths).
void GaussianSplat::sun_weights(const std::vector<double>& depth) {
    const GaussianMedium& medium = medium_;
    const std::size_t n = medium.size(), S = extra_.sun_w.size();
    gs_.resize(n * S);
    for (std::size_t j = 0; j < S; ++j) {
        const Vec3 u = -extra_.sun_w[j];  // towards the sun
        const double mu_s = u.z;
        Csun_.push_back(std::exp(-medium.optical_depth_ray(eye_, u, std::numeric_limits<double>::infinity(),
                                                           GaussianMedium::npos, false)));
        const RGB E = extra_.sun_E[j];
        const std::vector<double> Tg = gaussian_sun_depths(medium, u, threads_);
        parallel_chunks(n, threads_, 64, [&](std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) {
                const Vec3 c = medium.centre(i);
                const double Tsun = Tg[i] + sunlight_layer_depth(medium.beta0(), extra_.fog_top, mu_s, c.z);
                const double f1 = std::isinf(Tsun) ? 0.0 : std::exp(-depth[i] - Tsun) * kInv4Pi;
                GaussLightF& q = gs_[i * S + j];
                q.sx = q.sy = q.sz = 0.0f;
                q.wr = float(albedo_[3 * i] * E.x * f1);
                q.wg = float(albedo_[3 * i + 1] * E.y * f1);
                q.wb = float(albedo_[3 * i + 2] * E.z * f1);
                q.ke = 0.0f;
            }
        });
    }
}

void GaussianSplat::splat_gaussian(std::size_t i, int n, const float* dx, const float* dy, const float* dz,
                                   const float* tend, float* accT, float* accR, float* accG, float* accB) const {
    float Tvp[kTilePixels], Tvr[kTilePixels], tr[kTilePixels];
    const GaussF& g = g_[i];
    // (tend null: all inf, the reduced resolution's lattice)
    if (noise_.on()) {
        // Three vectorised passes: the unperturbed terms, the perturbed directions, the
        // optical depth along those (a fused loop, which the full resolution used, did not
        // vectorise: 3000 Gaussians with noise at 1080p took 122 s CPU).
        float qx[kTilePixels], qy[kTilePixels], qz[kTilePixels], s1[kTilePixels], s2[kTilePixels];
        if (tend) view_terms<false>(g, n, dx, dy, dz, tend, s1, Tvr, tr);
        else view_terms<true>(g, n, dx, dy, dz, tend, s1, Tvr, tr);
        noise_dirs(g.nscale, eye_f_, float(1.0 / noise_.scale), float(noise_.offset.x), float(noise_.offset.y),
                   float(noise_.offset.z), n, dx, dy, dz, tr, qx, qy, qz);
        if (tend) view_terms<false>(g, n, qx, qy, qz, tend, Tvp, s1, s2);
        else view_terms<true>(g, n, qx, qy, qz, tend, Tvp, s1, s2);
    } else if (tend) {
        if (g.far_eye) view_terms<false, true>(g, n, dx, dy, dz, tend, Tvp, Tvr, tr);
        else view_terms<false>(g, n, dx, dy, dz, tend, Tvp, Tvr, tr);
    } else {
        if (g.far_eye) view_terms<true, true>(g, n, dx, dy, dz, tend, Tvp, Tvr, tr);
        else view_terms<true>(g, n, dx, dy, dz, tend, Tvp, Tvr, tr);
    }
    add_to(Tvp, n, accT);
    const std::size_t L = lights_.size();
    if (!plain_) light_loop(i, n, dx, dy, dz, Tvp, Tvr, tr, accR, accG, accB);
    else
        for (std::size_t l = 0; l < L; ++l)
            (g.far_lights ? light_terms<true> : light_terms<false>)(g, gl_[i * L + l], lf_[l], n, dx, dy, dz, Tvp,
                                                                   Tvr, tr, accR, accG, accB);
}

void GaussianSplat::light_loop(std::size_t i, int n, const float* dx, const float* dy, const float* dz,
                               const float* Tvp, const float* Tvr, const float* tr, float* accR, float* accG,
                               float* accB) const {
    const GaussF& g = g_[i];
    const std::size_t L = lights_.size(), S = extra_.sun_w.size();
    const double gd = extra_.phase.kind == PhaseKind::HenyeyGreenstein ? extra_.phase.g : 0.0;
    const float g1 = float(gd), g2 = float(1.0 - gd * gd), g3 = float(1.0 + gd * gd);
    const PhaseKind kind = extra_.phase.kind;
    for (std::size_t l = 0; l < L; ++l)
        light_terms_phase(kind, !extra_.spot.empty() && extra_.spot[l], g, gl_[i * L + l], lf_[l], g1, g2, g3, n, dx,
                          dy, dz, Tvp, Tvr, tr, accR, accG, accB);
    for (std::size_t j = 0; j < S; ++j) {
        const Vec3& w = extra_.sun_w[j];
        sun_terms_phase(kind, g, gs_[i * S + j], float(-w.x), float(-w.y), float(-w.z), g1, g2, g3, n, dx, dy, dz,
                        Tvp, Tvr, tr, accR, accG, accB);
    }
}

void GaussianSplat::background_extra(const double* ddx, const double* ddy, const double* ddz, const float* far,
                                     const float* t0, int n, float (*L0)[3]) const {
    if (plain_ && extra_.custom_background.empty()) return;
    if (!extra_.background) return;
    const std::size_t L = lights_.size(), S = extra_.sun_w.size();
    for (std::size_t l = 0; l < L + S; ++l) {
        if (l < L && (extra_.custom_background.empty() || !extra_.custom_background[l])) continue;
        const RGB w = l < L ? weight0_[l] * Csv_[l] : medium_albedo_ * extra_.sun_E[l - L] * Csun_[l - L];
        if (w.x == 0.0 && w.y == 0.0 && w.z == 0.0) continue;
        for (int k = 0; k < n; ++k) {
            const double near = t0 ? double(t0[k]) : 0.0;
            const double v = double(far[k]) > near
                                 ? extra_.background(l, Vec3(ddx[k], ddy[k], ddz[k]), near, double(far[k]))
                                 : 0.0;
            for (int c = 0; c < 3; ++c) L0[k][c] += float(w[c] * v);
        }
    }
}

void GaussianSplat::homogeneous(const double* cos_gamma, std::size_t l, const float* Dvp, const float* t0, int n,
                                float* out) const {
    const double beta0 = medium_.beta0();
    if (!(beta0 > 0.0)) {
        std::fill(out, out + n, 0.0f);
        return;
    }
    const double Dsv = Dsv_[l];
    if (table_) {
        sun05_airlight_table_batch(table_->data().data(), table_->nu(), table_->nT(), beta0, Dsv, cos_gamma, Dvp, n,
                                   out, t0);
        return;
    }
    for (int k = 0; k < n; ++k) {
        const double near = t0 ? double(t0[k]) : 0.0;
        const double far = double(Dvp[k]);
        if (!(far > near)) {
            out[k] = 0.0f;
            continue;
        }
        double v = sun05_airlight(beta0, Dsv, cos_gamma[k], far, nullptr, FEval::Exact);
        if (near > 0.0)
            v = std::exp(beta0 * near) *
                std::max(0.0, v - sun05_airlight(beta0, Dsv, cos_gamma[k], near, nullptr, FEval::Exact));
        out[k] = float(v);
    }
}

void GaussianSplat::lattice_batch(const std::uint32_t* idx, int n, int m, const float* lx, const float* ly,
                                  const float* lz, float* T, float* R, float* G, float* B) const {
    // The Gaussians far from the eye and the lights (GaussF::far_eye, far_lights: one erfc
    // fewer per lane and light, ~20 % of a lane's cost) in a batch of their own, unless the
    // padding of two batches to whole SIMD vectors costs more than that saves.
    thread_local std::vector<std::uint32_t> far, other;
    far.clear();
    other.clear();
    for (int k = 0; k < n; ++k) (g_[idx[k]].far_eye && g_[idx[k]].far_lights ? far : other).push_back(idx[k]);
    auto lanes = [](std::size_t c) { return double((c + 15) / 16 * 16); };
    if (!far.empty() && !other.empty() && 0.8 * lanes(far.size()) + lanes(other.size()) >= lanes(std::size_t(n))) {
        other.assign(idx, idx + n);
        far.clear();
    }
    thread_local LatticeSoA q;
    const int L = int(lights_.size());
    for (const bool kfar : {true, false}) {
        const std::vector<std::uint32_t>& list = kfar ? far : other;
        const int nl = int(list.size());
        if (nl == 0) continue;
        const int n_pad = (nl + 15) / 16 * 16;
        for (auto* v : {&q.rx, &q.ry, &q.rz, &q.a, &q.a2, &q.k0, &q.ke}) v->resize(n_pad);
        for (auto* v : {&q.sx, &q.sy, &q.sz, &q.wr, &q.wg, &q.wb, &q.ske}) v->resize(std::size_t(n_pad) * L);
        q.scratch.resize(6 * std::size_t(n_pad));
        q.n = n_pad;
        for (int k = 0; k < n_pad; ++k) {
            // Padding: k0 = 0 and zero weights (terms 0), a = 1 (finite arithmetic).
            const bool pad = k >= nl;
            const std::uint32_t i = pad ? list[0] : list[k];
            const GaussF& g = g_[i];
            q.rx[k] = g.rx;
            q.ry[k] = g.ry;
            q.rz[k] = g.rz;
            q.a[k] = pad ? 1.0f : g.a;
            q.a2[k] = pad ? 1.0f : g.a2;
            q.k0[k] = pad ? 0.0f : g.k0;
            q.ke[k] = pad ? 0.0f : g.ke;
            for (int l = 0; l < L; ++l) {
                const GaussLightF& w = gl_[std::size_t(i) * L + l];
                const std::size_t o = std::size_t(l) * n_pad + k;
                q.sx[o] = w.sx;
                q.sy[o] = w.sy;
                q.sz[o] = w.sz;
                q.wr[o] = pad ? 0.0f : w.wr;
                q.wg[o] = pad ? 0.0f : w.wg;
                q.wb[o] = pad ? 0.0f : w.wb;
                q.ske[o] = pad ? 0.0f : w.ke;
            }
        }
        if (kfar) lattice_gaussian_major<true>(q, L, lf_.data(), m, lx, ly, lz, T, R, G, B);
        else lattice_gaussian_major<false>(q, L, lf_.data(), m, lx, ly, lz, T, R, G, B);
    }
}

GaussianSplat::ReducedCounts GaussianSplat::reduced_counts() const {
    return {n_lattice_.load(), n_exact_.load(), n_behind_.load(), n_coarse_.load(),
            n_far_.load(),     n_cancelled_.load(), far_gaussians_, far_nodes_, n_fine_.load()};
}

RGB GaussianSplat::eval_exact(const Vec3& dir, double Dvp) const {
    if (!exact_) exact_ = std::make_unique<FogshopAirlight>(medium_, eye_, lights_, table_, threads_);
    return exact_->eval_rgb(dir, Dvp, albedo_.data(), I0_.data(), medium_albedo_);
}

}  // namespace airlight
