// sun05_psf.cpp: PSF / NPSF of Sun et al. 2005 (section 6) and environment-map fog.
//
// PSF through one exact F difference. With t0 = tan(gamma/2) and u = Tsv sin(gamma),
//   F(u, pi/2) - F(u, gamma/2) = e^{-u t0} special_F_diff_exact(u, t0, inf),
// and Tsv cos(gamma) + u t0 = Tsv (cos g + sin^2 g / (1 + cos g)) = Tsv, so
//   PSF(gamma; Tsv) = Tsv e^{-Tsv} D(Tsv sin g, tan(g/2)) / (2 pi sin g),
//   D(u, t0) = e^{u t0} int_{t0}^inf e^{-u t} / (1 + t^2) dt        (no cancellation),
// and NPSF(gamma) = D(sin g, tan(g/2)) / (2 pi sin g) exactly (the paper's eq. 21 is PSF at
// Tsv = 1 divided by Tsv e^{-Tsv}); the factorisation (eq. 22) replaces D(Tsv sin g, .) by
// D(sin g, .). As gamma -> pi, D ~ 1/t0 and PSF -> Tsv e^{-Tsv} / (4 pi) (evaluated as that
// limit when sin gamma < 1e-7 on the back side).
#include "homogeneous/sun05_psf.h"
#include "core/constants.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>

#include "core/quadrature.h"
#include "gaussian/medium.h"  // parallel_chunks
#include "core/special_f.h"

namespace airlight {

namespace {


// D(u, t0) = e^{u t0} int_{t0}^inf e^{-u t} / (1 + t^2) dt = int_0^inf e^{-u x} / (1 + (t0 + x)^2) dx.
// For t0 >> 1 (gamma -> pi) special_F_diff_exact's angle substitution loses accuracy; there
// x = t0 y gives D = (1/t0) int_0^inf e^{-a y} t0^2 / (1 + t0^2 (1 + y)^2) dy, a = u t0, which
// is smooth (a = Tsv (1 - cos g) stays finite as gamma -> pi).
double psf_D(double u, double t0) {
    if (t0 < 1e3) return special_F_diff_exact(u, t0, INFINITY);
    const double a = u * t0, t02 = t0 * t0;
    const double h = integrate_adaptive([=](double y) { return std::exp(-a * y) * t02 / (1.0 + t02 * (1.0 + y) * (1.0 + y)); },
                                        0.0, INFINITY, 1e-12);
    return h / t0;
}

// The PSF without its factor Tsv e^{-Tsv}: D(u_scale sin g, tan(g/2)) / (2 pi sin g), from the
// sine and cosine of gamma (given separately: near 0 and pi the cosine alone loses the angle).
double psf_angular(double u_scale, double s, double c) {
    if (!(s > 0.0)) {
        if (c > 0.0) return INFINITY;  // looking straight at the source
        // gamma = pi: D ~ h(a) / t0 with t0 = s / (1 + c), so D / s -> h(a) / (1 - c) with
        // h(a) = int_0^inf e^{-a y} / (1 + y)^2 dy, a = u_scale (1 - c).
        const double a = u_scale * 2.0;
        const double h = integrate_adaptive([=](double y) { return std::exp(-a * y) / ((1.0 + y) * (1.0 + y)); }, 0.0,
                                            INFINITY, 1e-12);
        return h / (2.0 * kPi * 2.0);
    }
    const double t0 = c > -0.5 ? s / (1.0 + c) : (1.0 - c) / s;  // tan(gamma / 2), without cancellation
    return psf_D(u_scale * s, t0) / (2.0 * kPi * s);
}

double psf_angular_cos(double u_scale, double c) {
    c = std::clamp(c, -1.0, 1.0);
    return psf_angular(u_scale, std::sqrt(std::max(0.0, (1.0 - c) * (1.0 + c))), c);
}

void require(bool ok, const std::string& msg) {
    if (!ok) throw std::invalid_argument(msg);
}

// Normalised associated Legendre functions Pbar_l^m(x) = K_lm P_l^m(x) for 0 <= m <= l <= L,
// stored at index l (l + 1) / 2 + m (no Condon-Shortley phase: the same basis is used for
// projection and evaluation, so the phase convention cancels).
void legendre_normalised(int L, double x, std::vector<double>& P) {
    P.assign(size_t((L + 1) * (L + 2) / 2), 0.0);
    const double s = std::sqrt(std::max(0.0, (1.0 - x) * (1.0 + x)));
    auto at = [](int l, int m) { return size_t(l * (l + 1) / 2 + m); };
    double pmm = std::sqrt(1.0 / (4.0 * kPi));
    for (int m = 0; m <= L; ++m) {
        if (m > 0) pmm *= std::sqrt((2.0 * m + 1.0) / (2.0 * m)) * s;
        P[at(m, m)] = pmm;
        if (m + 1 <= L) P[at(m + 1, m)] = std::sqrt(2.0 * m + 3.0) * x * pmm;
        for (int l = m + 2; l <= L; ++l) {
            const double a = std::sqrt((4.0 * l * l - 1.0) / (double(l) * l - double(m) * m));
            const double b = std::sqrt((double(l - 1) * (l - 1) - double(m) * m) / (4.0 * (l - 1) * (l - 1) - 1.0));
            P[at(l, m)] = a * (x * P[at(l - 1, m)] - b * P[at(l - 2, m)]);
        }
    }
}

// Polar angle (from +Z) of the centre of row j of an equirectangular map of _height_ rows
// (row 0 at the top) and the exact solid-angle factor of the row per unit azimuth.
double row_theta(int j, int height) { return kPi * (j + 0.5) / height; }
double row_band(int j, int height) {
    return std::cos(kPi * j / height) - std::cos(kPi * (j + 1.0) / height);
}

void check_map(const EnvironmentMap& map, const char* what) {
    require(map.width > 0 && map.height > 0, std::string(what) + ": empty environment map");
    require(map.rgb.size() == size_t(3) * map.width * map.height,
            std::string(what) + ": pixel array does not match width x height x 3");
    for (float f : map.rgb)
        require(std::isfinite(f) && f >= 0.0f,
                std::string(what) + ": environment texels must be finite and >= 0 (got " + std::to_string(f) + ")");
}

}  // namespace

double sun05_psf(double Tsv, double cos_gamma) {
    require(std::isfinite(Tsv) && Tsv > 0.0, "sun05_psf: need finite Tsv > 0");
    require(!std::isnan(cos_gamma), "sun05_psf: cos_gamma is NaN");
    return Tsv * std::exp(-Tsv) * psf_angular_cos(Tsv, cos_gamma);
}

double sun05_npsf(double cos_gamma) {
    require(!std::isnan(cos_gamma), "sun05_npsf: cos_gamma is NaN");
    return psf_angular_cos(1.0, cos_gamma);
}

double sun05_psf_angle(double Tsv, double gamma) {
    require(std::isfinite(Tsv) && Tsv > 0.0, "sun05_psf: need finite Tsv > 0");
    require(gamma >= 0.0 && gamma <= kPi, "sun05_psf_angle: need gamma in [0, pi]");
    return Tsv * std::exp(-Tsv) * psf_angular(Tsv, std::sin(gamma), std::cos(gamma));
}

double sun05_npsf_angle(double gamma) {
    require(gamma >= 0.0 && gamma <= kPi, "sun05_npsf_angle: need gamma in [0, pi]");
    return psf_angular(1.0, std::sin(gamma), std::cos(gamma));
}

std::vector<double> zonal_eigenvalues(const std::function<double(double)>& kernel_of_gamma, int L) {
    require(L >= 0 && L <= 512, "zonal_eigenvalues: need 0 <= L <= 512");
    // Composite 16-point Gauss-Legendre in gamma: geometric panels from 1e-12 to 0.05 (the
    // integrand k(g) sin(g) is bounded but has a log-like layer at 0), then uniform panels
    // no wider than the oscillation of P_L allows.
    std::vector<double> gx, gw;
    gauss_legendre(16, gx, gw);
    std::vector<double> edges{0.0};
    for (double e = 1e-12; e < 0.05; e *= 4.0) edges.push_back(e);
    const int n_uniform = std::max(64, 4 * L);
    for (int i = 0; i <= n_uniform; ++i) edges.push_back(0.05 + (kPi - 0.05) * i / n_uniform);
    std::vector<double> lambda(size_t(L) + 1, 0.0);
    for (size_t p = 0; p + 1 < edges.size(); ++p) {
        const double a = edges[p], b = edges[p + 1], half = 0.5 * (b - a), mid = 0.5 * (a + b);
        for (int q = 0; q < 16; ++q) {
            const double g = mid + half * gx[q];
            const double w = half * gw[q] * kernel_of_gamma(g) * std::sin(g);
            const double x = std::cos(g);
            double p0 = 1.0, p1 = x;
            lambda[0] += w;
            if (L >= 1) lambda[1] += w * x;
            for (int l = 2; l <= L; ++l) {
                const double p2 = ((2.0 * l - 1.0) * x * p1 - (l - 1.0) * p0) / l;
                p0 = p1;
                p1 = p2;
                lambda[size_t(l)] += w * p2;
            }
        }
    }
    for (double& v : lambda) v *= 2.0 * kPi;
    return lambda;
}

std::vector<double> psf_eigenvalues(double Tsv, int L, PsfKind kind) {
    require(std::isfinite(Tsv) && Tsv > 0.0, "psf_eigenvalues: need finite Tsv > 0");
    if (kind == PsfKind::Exact)
        return zonal_eigenvalues([Tsv](double g) { return sun05_psf_angle(Tsv, g); }, L);
    static std::mutex mutex;
    static std::map<int, std::vector<double>> cache;
    std::vector<double> npsf;
    {
        std::lock_guard<std::mutex> lock(mutex);
        auto it = cache.lower_bound(L);
        if (it != cache.end()) npsf = it->second;
    }
    if (npsf.empty()) {
        npsf = zonal_eigenvalues([](double g) { return sun05_npsf_angle(g); }, L);
        std::lock_guard<std::mutex> lock(mutex);
        cache[L] = npsf;
    }
    npsf.resize(size_t(L) + 1);
    const double amplitude = Tsv * std::exp(-Tsv);
    for (double& v : npsf) v *= amplitude;
    return npsf;
}

// Blender's Environment Texture mapping (measured in tests/blender/test_environment.py).
void equirect_uv(const Vec3& d, double& u, double& v) {
    const double len = glm::length(d);
    u = 0.5 - std::atan2(d.y, d.x) / (2.0 * kPi);
    if (u < 0.0) u += 1.0;
    if (u >= 1.0) u -= 1.0;
    v = 1.0 - std::acos(std::clamp(d.z / len, -1.0, 1.0)) / kPi;
}

Vec3 equirect_direction(double u, double v) {
    const double phi = (0.5 - u) * 2.0 * kPi, theta = (1.0 - v) * kPi;
    return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

RGB environment_lookup(const EnvironmentMap& map, const Vec3& d) {
    double u, v;
    equirect_uv(d, u, v);
    // Texel centres at ((i + 1/2) / W, 1 - (j + 1/2) / H); row 0 is the top.
    const double x = u * map.width - 0.5, y = (1.0 - v) * map.height - 0.5;
    const double fx = std::floor(x), fy = std::floor(y);
    const double ax = x - fx, ay = y - fy;
    const int i0 = int(fx), j0 = int(fy);
    RGB out(0.0);
    for (int dj = 0; dj < 2; ++dj) {
        const int j = std::clamp(j0 + dj, 0, map.height - 1);
        const double wy = dj ? ay : 1.0 - ay;
        for (int di = 0; di < 2; ++di) {
            int i = (i0 + di) % map.width;
            if (i < 0) i += map.width;
            const double w = wy * (di ? ax : 1.0 - ax);
            const float* t = &map.rgb[3 * (size_t(j) * map.width + i)];
            out += w * RGB(t[0], t[1], t[2]);
        }
    }
    return out;
}

ShCoefficients sh_project(const EnvironmentMap& map, int L) {
    check_map(map, "sh_project");
    require(L >= 0 && L <= 256, "sh_project: need 0 <= L <= 256");
    // Texels are taken as constant over their (theta, phi) cells and the basis is integrated
    // over each cell exactly (up to the quadrature in cos theta: 8 Gauss points per row, exact
    // for polynomials of degree 15 in cos theta per row), so a constant map has exactly one
    // nonzero coefficient and the projection is independent of where texel centres fall.
    ShCoefficients sh;
    sh.L = L;
    sh.c.assign(size_t((L + 1) * (L + 1)), RGB(0.0));
    const int W = map.width;
    const double dphi = 2.0 * kPi / W;
    std::vector<double> gx, gw, P, Pacc(size_t((L + 1) * (L + 2) / 2));
    gauss_legendre(8, gx, gw);
    std::vector<double> cm(size_t(W) * (L + 1)), sm(size_t(W) * (L + 1));
    for (int i = 0; i < W; ++i) {
        const double phi = (0.5 - (i + 0.5) / W) * 2.0 * kPi;
        for (int m = 0; m <= L; ++m) {
            // int over the cell of cos / sin (m phi) dphi = dphi sinc(m dphi / 2) cos / sin (m phi_c)
            const double x = 0.5 * m * dphi, sinc = m ? std::sin(x) / x : 1.0;
            cm[size_t(i) * (L + 1) + m] = dphi * sinc * std::cos(m * phi);
            sm[size_t(i) * (L + 1) + m] = dphi * sinc * std::sin(m * phi);
        }
    }
    std::vector<RGB> C(size_t(L) + 1), S(size_t(L) + 1);
    for (int j = 0; j < map.height; ++j) {
        const double mu_hi = std::cos(kPi * j / map.height), mu_lo = std::cos(kPi * (j + 1.0) / map.height);
        std::fill(Pacc.begin(), Pacc.end(), 0.0);
        for (int q = 0; q < 8; ++q) {
            legendre_normalised(L, 0.5 * (mu_hi + mu_lo) + 0.5 * (mu_hi - mu_lo) * gx[size_t(q)], P);
            const double w = 0.5 * (mu_hi - mu_lo) * gw[size_t(q)];
            for (size_t k = 0; k < P.size(); ++k) Pacc[k] += w * P[k];
        }
        std::fill(C.begin(), C.end(), RGB(0.0));
        std::fill(S.begin(), S.end(), RGB(0.0));
        for (int i = 0; i < W; ++i) {
            const float* t = &map.rgb[3 * (size_t(j) * W + i)];
            const RGB Lt(t[0], t[1], t[2]);
            for (int m = 0; m <= L; ++m) {
                C[size_t(m)] += Lt * cm[size_t(i) * (L + 1) + m];
                S[size_t(m)] += Lt * sm[size_t(i) * (L + 1) + m];
            }
        }
        for (int l = 0; l <= L; ++l) {
            const size_t base = size_t(l * (l + 1));
            sh.c[base] += Pacc[size_t(l * (l + 1) / 2)] * C[0];
            for (int m = 1; m <= l; ++m) {
                const double k = std::sqrt(2.0) * Pacc[size_t(l * (l + 1) / 2 + m)];
                sh.c[base + m] += k * C[size_t(m)];
                sh.c[base - m] += k * S[size_t(m)];
            }
        }
    }
    return sh;
}

EnvironmentMap sh_reconstruct(const ShCoefficients& sh, int width, int height) {
    require(width > 0 && height > 0, "sh_reconstruct: need a positive size");
    const int L = sh.L;
    EnvironmentMap out;
    out.width = width;
    out.height = height;
    out.rgb.assign(size_t(3) * width * height, 0.0f);
    std::vector<double> P;
    std::vector<RGB> A(size_t(L) + 1), B(size_t(L) + 1);
    for (int j = 0; j < height; ++j) {
        legendre_normalised(L, std::cos(row_theta(j, height)), P);
        // Per m: A_m = sum_l Pbar_lm c_l,m, B_m = sum_l Pbar_lm c_l,-m.
        for (int m = 0; m <= L; ++m) {
            A[size_t(m)] = B[size_t(m)] = RGB(0.0);
            for (int l = m; l <= L; ++l) {
                const double p = P[size_t(l * (l + 1) / 2 + m)] * (m ? std::sqrt(2.0) : 1.0);
                A[size_t(m)] += p * sh.c[size_t(l * (l + 1) + m)];
                if (m) B[size_t(m)] += p * sh.c[size_t(l * (l + 1) - m)];
            }
        }
        for (int i = 0; i < width; ++i) {
            const double phi = (0.5 - (i + 0.5) / width) * 2.0 * kPi;
            RGB v = A[0];
            for (int m = 1; m <= L; ++m) v += A[size_t(m)] * std::cos(m * phi) + B[size_t(m)] * std::sin(m * phi);
            float* t = &out.rgb[3 * (size_t(j) * width + i)];
            t[0] = float(v.x);
            t[1] = float(v.y);
            t[2] = float(v.z);
        }
    }
    return out;
}

void sh_convolve(ShCoefficients& sh, const std::vector<double>& lambda) {
    require(int(lambda.size()) > sh.L, "sh_convolve: need an eigenvalue for every band");
    for (int l = 0; l <= sh.L; ++l)
        for (int m = -l; m <= l; ++m) sh.c[size_t(l * (l + 1) + m)] *= lambda[size_t(l)];
}

RGB sh_irradiance(const ShCoefficients& sh, const Vec3& n_in) {
    require(sh.L >= 2, "sh_irradiance: need bands up to l = 2");
    const Vec3 n = glm::normalize(n_in);
    // Evaluate Y_lm(n) for l <= 2 with the same basis as sh_project.
    std::vector<double> P;
    legendre_normalised(2, n.z, P);
    const double phi = std::atan2(n.y, n.x);
    const double A[3] = {kPi, 2.0 * kPi / 3.0, kPi / 4.0};
    RGB E(0.0);
    for (int l = 0; l <= 2; ++l) {
        E += A[l] * P[size_t(l * (l + 1) / 2)] * sh.c[size_t(l * (l + 1))];
        for (int m = 1; m <= l; ++m) {
            const double k = A[l] * std::sqrt(2.0) * P[size_t(l * (l + 1) / 2 + m)];
            E += k * (std::cos(m * phi) * sh.c[size_t(l * (l + 1) + m)] + std::sin(m * phi) * sh.c[size_t(l * (l + 1) - m)]);
        }
    }
    return E;
}

EnvironmentMap convolve_direct(const EnvironmentMap& map, const std::function<double(double)>& kernel_of_cos,
                               int out_width, int out_height, int threads) {
    check_map(map, "convolve_direct");
    require(out_width > 0 && out_height > 0, "convolve_direct: need a positive output size");
    const int W = map.width, H = map.height;
    constexpr int kSub = 8;
    // Source texel directions and solid angles (sub-texels for the near field).
    std::vector<Vec3> dir(size_t(W) * H);
    std::vector<double> dw(static_cast<size_t>(H));
    for (int j = 0; j < H; ++j) {
        dw[size_t(j)] = row_band(j, H) * 2.0 * kPi / W;
        for (int i = 0; i < W; ++i) dir[size_t(j) * W + i] = equirect_direction((i + 0.5) / W, 1.0 - (j + 0.5) / H);
    }
    const double texel_angle = std::max(2.0 * kPi / W, kPi / H);
    const double near_cos = std::cos(std::min(kPi, 3.0 * texel_angle));
    EnvironmentMap out;
    out.width = out_width;
    out.height = out_height;
    out.rgb.assign(size_t(3) * out_width * out_height, 0.0f);
    // Mean of the kernel over a cap of solid angle a centred on the direction (used for the
    // sub-texel that contains the output direction, where the point value is singular).
    auto cap_mean = [&](double a) {
        const double rho = std::acos(std::clamp(1.0 - a / (2.0 * kPi), -1.0, 1.0));
        const double integral = integrate_adaptive(
            [&](double g) { return kernel_of_cos(std::cos(g)) * std::sin(g); }, 0.0, rho, 1e-8);
        return 2.0 * kPi * integral / a;
    };
    parallel_chunks(size_t(out_height), threads, 1, [&](size_t r0, size_t r1) {
        // cap_mean per source sub-row (its solid angle depends on the sub-row only).
        std::vector<double> cap_cache(size_t(H) * kSub, -1.0);
        for (size_t jo = r0; jo < r1; ++jo) {
            for (int io = 0; io < out_width; ++io) {
                const Vec3 w = equirect_direction((io + 0.5) / out_width, 1.0 - (jo + 0.5) / out_height);
                RGB sum(0.0);
                for (int j = 0; j < H; ++j) {
                    for (int i = 0; i < W; ++i) {
                        const float* t = &map.rgb[3 * (size_t(j) * W + i)];
                        if (t[0] == 0.0f && t[1] == 0.0f && t[2] == 0.0f) continue;
                        const RGB Lt(t[0], t[1], t[2]);
                        const double c = glm::dot(w, dir[size_t(j) * W + i]);
                        if (c < near_cos) {
                            sum += Lt * (dw[size_t(j)] * kernel_of_cos(c));
                            continue;
                        }
                        // Near field: kSub x kSub sub-texels (equal-angle split; exact
                        // solid angles per sub-row).
                        for (int sj = 0; sj < kSub; ++sj) {
                            const double th0 = kPi * (j + double(sj) / kSub) / H;
                            const double th1 = kPi * (j + (sj + 1.0) / kSub) / H;
                            const double a = (std::cos(th0) - std::cos(th1)) * 2.0 * kPi / (W * kSub);
                            for (int si = 0; si < kSub; ++si) {
                                const double u = (i + (si + 0.5) / kSub) / W;
                                const double v = 1.0 - (0.5 * (th0 + th1)) / kPi;
                                const double cs = glm::dot(w, equirect_direction(u, v));
                                const double sub_angle = std::sqrt(a / kPi);
                                double k;
                                if (cs > std::cos(0.5 * sub_angle)) {
                                    double& cached = cap_cache[size_t(j) * kSub + sj];
                                    if (cached < 0.0) cached = cap_mean(a);
                                    k = cached;
                                } else {
                                    k = kernel_of_cos(cs);
                                }
                                sum += Lt * (a * k);
                            }
                        }
                    }
                }
                float* o = &out.rgb[3 * (jo * out_width + io)];
                o[0] = float(sum.x);
                o[1] = float(sum.y);
                o[2] = float(sum.z);
            }
        }
    });
    return out;
}

EnvironmentFog environment_fog(const EnvironmentMap& world, double sigma_t, double distance, int sh_order,
                               int out_width, int out_height, PsfKind kind, int threads) {
    check_map(world, "environment_fog");
    require(std::isfinite(sigma_t) && sigma_t >= 0.0, "environment_fog: density must be finite and >= 0");
    require(std::isfinite(distance) && distance > 0.0, "environment_fog: the environment distance must be > 0");
    require(out_width > 0 && out_height > 0, "environment_fog: need a positive output size");
    require(sh_order <= 128, "environment_fog: sh_order above 128 is not supported");
    EnvironmentFog fog;
    const double Tsv = sigma_t * distance;
    fog.transmittance = std::exp(-Tsv);
    const int L = std::max(2, sh_order);
    fog.sh_world = sh_project(world, 2);
    if (Tsv == 0.0) {
        fog.lambda.assign(size_t(L) + 1, 0.0);
        fog.glow.width = out_width;
        fog.glow.height = out_height;
        fog.glow.rgb.assign(size_t(3) * out_width * out_height, 0.0f);
        return fog;
    }
    fog.lambda = psf_eigenvalues(Tsv, L, sh_order >= 0 ? kind : PsfKind::Exact);
    const std::vector<double>& lambda = fog.lambda;
    if (sh_order >= 0) {
        ShCoefficients conv = sh_project(world, sh_order);
        sh_convolve(conv, lambda);
        fog.glow = sh_reconstruct(conv, out_width, out_height);
        // Truncation rings (Gibbs) can dip below zero next to a bright source: radiance can't.
        for (float& f : fog.glow.rgb) f = std::max(f, 0.0f);
    } else {
        fog.glow = convolve_direct(world, [Tsv](double c) { return sun05_psf(Tsv, c); }, out_width, out_height,
                                   threads);
    }
    return fog;
}

void environment_irradiance(const EnvironmentFog& fog, const RGB& albedo, const Vec3& n, RGB& E_world,
                            RGB& E_fogged) {
    require(fog.lambda.size() >= 3, "environment_irradiance: the fog has no eigenvalues");
    E_world = sh_irradiance(fog.sh_world, n);
    ShCoefficients glow = fog.sh_world;
    sh_convolve(glow, fog.lambda);
    E_fogged = fog.transmittance * E_world + albedo * sh_irradiance(glow, n);
}

}  // namespace airlight
