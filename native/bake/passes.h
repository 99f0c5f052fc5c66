// passes.h: the passes of a bake, in the order bake() runs them (bake.cpp):
//   1. raycast_pass      camera rays and the depth of the first hit per pixel centre
//   2. gaussian_pass     Gaussian fog by the tiled splat (perspective camera, Fogshop models),
//                        refined to the asked accuracy (refine_pass)
//   3. homogeneous_pass  the fog at every other pixel centre (exact, or on a lattice), and
//                        the edge pixels (depth discontinuities: EdgeMap)
//   4. edge_pass         the edge pixels supersampled through the render's pixel filter
//   5. surface_pass      the lights' attenuation and the fog's glow on surfaces (surface_pass.h)
// Each works on the BakeContext's images; the fog comes from the FogEvaluator.
#pragma once

#include <utility>
#include <vector>

#include "bake/context.h"
#include "bake/edges.h"
#include "bake/fog_evaluator.h"

namespace airlight {

// Per band of kBandRows rows, its edge pixels (row, column), in order.
struct EdgePixels {
    explicit EdgePixels(size_t n_bands) : per_band(n_bands) {}
    std::vector<std::vector<std::pair<int, int>>> per_band;
};

void raycast_pass(BakeContext& ctx);
// Returns where the progress bar stands after it.
double gaussian_pass(BakeContext& ctx, const FogEvaluator& fog);
// Inside gaussian_pass: the Gaussian refinement (FogEvaluator::refine_gaussians) of the
// centre samples, whose Fogshop values (the splat's) are _fogshop_ (refine_pass.cpp); it
// reports progress from _progress_begin_ to _progress_end_ and stops on cancel.
void refine_pass(BakeContext& ctx, const FogEvaluator& fog, const std::vector<float>& fogshop, double progress_begin,
                 double progress_end);
// _splatted_: the Gaussian pass wrote the centre samples; only the edge pixels are found.
EdgePixels homogeneous_pass(BakeContext& ctx, const FogEvaluator& fog, const EdgeMap& edges, bool splatted,
                            double progress_begin, double progress_end);
void edge_pass(BakeContext& ctx, const FogEvaluator& fog, const EdgePixels& edges, double progress_begin);

}  // namespace airlight
