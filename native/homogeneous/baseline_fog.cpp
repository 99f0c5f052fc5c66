// baseline_fog.cpp: constant-colour fog fit and error statistics (see baseline_fog.h).
#include "homogeneous/baseline_fog.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace airlight {

double baseline_fog_fit(const double* La, const double* D, std::size_t n, double sigma_t) {
    double num = 0.0, den = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double f = -std::expm1(-sigma_t * D[i]);
        num += La[i] * f;
        den += f * f;
    }
    return den > 0.0 ? num / den : 0.0;
}

ErrorStats relative_error_stats(const double* got, const double* want, std::size_t n) {
    std::vector<double> e;
    e.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
        if (want[i] > 0.0) e.push_back(std::abs(got[i] - want[i]) / want[i]);
    ErrorStats s;
    if (e.empty()) return s;
    for (double v : e) s.mean += v;
    s.mean /= e.size();
    std::sort(e.begin(), e.end());
    s.max = e.back();
    s.p99 = e[std::min(e.size() - 1, static_cast<std::size_t>(0.99 * e.size()))];
    return s;
}

}  // namespace airlight
