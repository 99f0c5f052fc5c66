// screen_crossings.h: the shadow volumes' crossings with the camera's own rays, found by
// rasterizing the volumes' faces on the film instead of tracing every ray through Embree.
//
// Every camera ray of a perspective view leaves one point, the viewer, so whether it crosses
// a face is a 2D question on the film: the face covers the film position. In homogeneous
// film coordinates (Olano & Greer 1997) a face's vertices are q_i = M^-1 P_i (P_i relative to
// the viewer, M = [Dx Dy D0] the camera's affine ray directions) and the ray through (x, y)
// crosses the face ahead of the viewer exactly where the three edge functions
// sign(det q) (q_i x q_j) . (x, y, 1) are >= 0: no clipping at the viewer's plane, and faces
// reaching behind it are handled as they are. A shared edge has, in the neighbouring face,
// the exact negation of its edge function (the cross product and the dot product negate
// exactly in IEEE arithmetic, with no contraction to fma: -ffp-contract=off), and a film
// position exactly on an edge goes to the face whose edge normal points in +x (then +y): the
// faces of a volume tile the film without gaps or overlaps, as Embree's watertight test
// tiles it for the rays it traces. The crossing's distance is exact along the caller's unit
// ray, t = (N . P0) / (N . d), and its weight's sign that of N . P0 (N: Embree's normal).
//
// Faces are binned into tiles of the film (a margin around the image holds the edge pixels'
// sub-samples); a query visits its tile's faces, a row of pixel centres the faces' exact
// spans on the row. A scene whose faces would need more than _max_entries_ tile entries, or
// more than kMaxFacesPerTile per tile on average, or more faces than kMaxFacesPerPixel per
// pixel (heavy casters: counted before anything is built), is not binned (ready() false): the
// caller traces with Embree.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "image/camera.h"
#include "shadow/shadow_volumes.h"

namespace airlight {

class ScreenCrossings {
  public:
    // The faces of _volumes_ seen by a perspective camera at _viewer_ (the world) whose
    // unnormalised ray direction through film position (x, y) is D0 + x Dx + y Dy
    // (CameraRays::affine_direction), for a W x H image. The caps (the casters' own
    // triangles) of the casters the camera sees (ShadowFaces::n_seen_caps) wholly farther
    // than _cap_reach_ from the viewer and nearer than _cap_beyond_ are left out
    // (ShadowVolumes::cap_left_out): the rays end on those casters, so a ray meets none before
    // its end but within the near clip or past the far clip (pass the farthest start of a
    // ray and the far clip's depth; the defaults keep them all).
    // Volumes of more faces than _max_faces_per_pixel_ per pixel (and kMinFacesForFallback)
    // are not binned at all (ready() false), decided before any face is built.
    ScreenCrossings(const ShadowVolumes& volumes, const Vec3& viewer, const Vec3& D0, const Vec3& Dx, const Vec3& Dy,
                    int W, int H,
                    double cap_reach = std::numeric_limits<double>::infinity(), double cap_beyond = 0.0,
                    int threads = 1, size_t max_entries = size_t(1) << 26, size_t max_faces_per_tile = kMaxFacesPerTile,
                    double max_faces_per_pixel = kMaxFacesPerPixel);
    bool ready() const { return ready_; }
    // Into lists[k] (cleared first): the crossings with 0 < t < t1[k] of the _n_ rays
    // through film positions film[k], with unit directions rays[k].d (from the viewer). A
    // row of pixel centres (equal y, x one apart) takes each face's span at once. False, with
    // nothing written, when a position lies outside the binned film.
    // _masks_ (optional): per ray, the lights asked for (ShadowVolumes::light_mask bits).
    bool crossings(const glm::dvec2* film, const Ray* rays, const float* t1, int n, std::vector<Crossing>* lists,
                   const uint32_t* masks = nullptr) const;
    size_t num_faces() const { return faces_.size(); }
    size_t num_entries() const { return entries_.size(); }

  private:
    struct Face {
        double e[3][3];  // edge functions: inside where e[k] . (x, y, 1) >= 0 for every k
        bool tie[3];     // a film position with e[k] . (x, y, 1) == 0 is inside
        Vec3 N;          // Embree's normal (v1 - v0) x (v2 - v0), relative to the viewer
        double NP0;      // N . P0: t = NP0 / (N . d)
        float near;      // the face's distance from the viewer (a lower bound of t)
        int16_t light, dw;
    };
    struct Box {  // a face's film bounding box (empty: unbounded, it reaches behind the viewer)
        double x0 = std::numeric_limits<double>::infinity(), x1 = -std::numeric_limits<double>::infinity();
        double y0 = std::numeric_limits<double>::infinity(), y1 = -std::numeric_limits<double>::infinity();
    };
    // Whether face _f_ covers film position (x, y) (the one formula every query uses).
    static bool covers(const Face& f, double x, double y);
    void bin(const std::vector<Face>& faces, const std::vector<Box>& boxes, size_t max_entries, size_t max_per_tile,
             int threads);
    void row_crossings(const glm::dvec2* film, const Ray* rays, const float* t1, int n,
                       std::vector<Crossing>* lists, const uint32_t* masks) const;
    static bool asked(const uint32_t* masks, int k, const Face& f) {
        return !masks || (masks[k] & ShadowVolumes::light_mask(f.light));
    }
    // A lower bound of the distance at which the rays of film row _y_ between _xa_ and _xb_
    // cross face _f_'s plane.
    double span_near(const Face& f, double xa, double xb, double y) const;
    void push(const Face& f, const Ray& ray, float t1, std::vector<Crossing>& list) const;

    static constexpr int kTileW = 64, kTileH = 8;
    static constexpr double kMargin = 4.0;  // film margin around the image, pixels
  public:
    // The mean faces per tile above which the film costs more than tracing (bench_shadows.py:
    // the street ~40, faster on the film; with 10^3 small open casters ~10^3, no faster).
    static constexpr size_t kMaxFacesPerTile = 160;
    static constexpr size_t kMinTilesForFallback = 1000;
    // The faces per pixel above which building and binning them costs more than tracing the
    // rays saves: each face costs ~1.5 us to set up, the film saves ~75 ns a pixel (the street
    // at 1920x1080 with a grid of N triangles added as a caster, 4 lamps: film / traced bake
    // 0.36 / 0.44 s at N = 1e4, 0.54 / 0.50 s at 3e4, 7.7 / 1.5 s at 1e6; at 480x270 0.73 /
    // 0.08 s at 1e5). Below kMinFacesForFallback faces the film is kept (a few ms at most).
    static constexpr double kMaxFacesPerPixel = 0.05;
    static constexpr size_t kMinFacesForFallback = 4096;

  private:
    Vec3 D0_{0.0}, Dx_{0.0}, Dy_{0.0};  // the camera's affine ray directions
    int nx_ = 0, ny_ = 0;
    bool ready_ = false;
    std::vector<Face> faces_;
    std::vector<uint32_t> begin_;    // per tile (row-major), into entries_; nx_ * ny_ + 1
    std::vector<uint32_t> entries_;  // face indices
};

}  // namespace airlight
