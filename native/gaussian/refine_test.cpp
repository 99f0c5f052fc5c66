// refine_test.cpp: the refinement's plan (gaussian/refine.h). A light refined whole (the
// bake's marched point and spot lights) is decided by its pairs' light terms alone, and the
// plan then agrees with the full bounds on which lights need refining.
#include "gaussian/refine.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace airlight {
namespace {

GaussianMedium random_cloud(int n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> ux(-6.0, 6.0), uy(-2.5, 3.0), uz(-22.0, -10.0), ua(0.4, 1.5), uc(0.02, 0.6);
    std::vector<double> b, a, c;
    for (int i = 0; i < n; ++i) {
        b.insert(b.end(), {ux(rng), uy(rng), uz(rng)});
        a.push_back(ua(rng));
        c.push_back(uc(rng));
    }
    return GaussianMedium(b, a, c, 0.0);
}

TEST(GaussianRefinePlan, WholeLightsNeedOnePair) {
    const GaussianMedium m = random_cloud(300, 4);
    const PhaseFunction iso{};
    std::vector<RefineLight> lights(3);
    lights[0].s = Vec3(0.0, 0.0, -15.0);    // inside the cloud: pairs over any target
    lights[1].s = Vec3(0.0, 200.0, -15.0);  // far above it: its light terms are small
    lights[2].kind = GaussianRefLight::Kind::Sun;
    lights[2].w = glm::normalize(Vec3(0.3, -0.8, -0.5));
    const double target = 0.02;
    const GaussianRefinePlan full = plan_gaussian_refinement(m, Vec3(0.0), lights, iso, target, 2);
    const GaussianRefinePlan fast = plan_gaussian_refinement(m, Vec3(0.0), lights, iso, target, 2, {1, 1, 0});
    auto pairs_of = [](const GaussianRefinePlan& p, std::uint32_t l) {
        return std::count_if(p.refined.begin(), p.refined.end(), [&](const RefinePair& q) { return q.light == l; });
    };
    EXPECT_EQ(full.pairs, fast.pairs);
    // The near light: refined in both, by one pair of the whole-light plan, over the target.
    ASSERT_GT(pairs_of(full, 0), 1);
    ASSERT_EQ(pairs_of(fast, 0), 1);
    for (const RefinePair& q : fast.refined)
        if (q.light == 0) EXPECT_GT(q.bound, target);
    // The far light (its light terms under the target: its pairs' full bounds decide) and the
    // sun: the same pairs and bounds either way.
    for (std::uint32_t l : {1u, 2u}) EXPECT_EQ(pairs_of(full, l), pairs_of(fast, l)) << l;
    for (std::size_t k = 0; k < full.refined.size(); ++k)
        if (full.refined[k].light != 0) {
            const auto it = std::find_if(fast.refined.begin(), fast.refined.end(), [&](const RefinePair& q) {
                return q.light == full.refined[k].light && q.gaussian == full.refined[k].gaussian;
            });
            ASSERT_NE(it, fast.refined.end());
            EXPECT_EQ(it->bound, full.refined[k].bound);
        }
    // What is left to Fogshop: not the near light's pairs any more (it is refined whole).
    EXPECT_LE(fast.kept_bound, full.kept_bound);
    EXPECT_LE(fast.kept_bound, target);
}

}  // namespace
}  // namespace airlight
