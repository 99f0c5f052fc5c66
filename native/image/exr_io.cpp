// exr_io.cpp: one multilayer float (or half) EXR with an RGB triple per pass, via
// OpenImageIO (the passes interleaved, and rounded to half, in parallel here).
#include "image/exr_io.h"

#include "core/memory.h"
#include "core/parallel.h"

#include <Imath/half.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <thread>

namespace airlight {

namespace {

const char* const kCompressions[] = {"none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"};

// Rows interleaved and written at a time: a multiple of every compression's block (PIZ and
// B44: 32 rows, DWAB 256), enough blocks for every thread.
constexpr int kStripRows = 256;

// OpenEXR's compression threads, set once for the process: every hardware thread.
void use_all_threads() {
    static const bool done = [] {
        OIIO::attribute("exr_threads", int(std::max(1u, std::thread::hardware_concurrency())));
        return true;
    }();
    (void)done;
}

}  // namespace

void write_multilayer_exr(const std::string& path, int width, int height,
                          const std::vector<ExrPass>& passes, const std::string& layer_prefix, bool half,
                          const std::string& compression) {
    const std::string method = compression == "auto" ? (half ? "zip" : "piz") : compression;
    // "auto" halves: ZIP at zlib's level 1 (benchmarks/bench_exr.py: 1.4x faster than its
    // default level for a 1.35x larger file, half of PIZ's).
    const std::string attribute = compression == "auto" && half ? "zip:1" : method;
    if (std::find(std::begin(kCompressions), std::end(kCompressions), method) == std::end(kCompressions))
        throw std::invalid_argument("write_exr: unknown compression '" + compression +
                                    "' (auto, none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa or dwab)");
    use_all_threads();
    // Check the arguments; OIIO would otherwise fail with a less helpful message.
    if (width <= 0 || height <= 0) throw std::invalid_argument("EXR size must be positive");
    if (passes.empty()) throw std::invalid_argument("write_multilayer_exr: no passes given");
    for (const ExrPass& pass : passes)
        if (pass.name.empty() || !pass.rgb)
            throw std::invalid_argument("write_multilayer_exr: pass without name or data");

    // Describe one part with channels "<prefix><name>.R/G/B" per pass.
    const int nchannels = 3 * int(passes.size());
    OIIO::ImageSpec spec(width, height, nchannels, half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
    spec.channelnames.clear();
    for (const ExrPass& pass : passes)
        for (const char* c : {".R", ".G", ".B"}) spec.channelnames.push_back(layer_prefix + pass.name + c);
    spec.alpha_channel = -1;
    spec.attribute("compression", attribute);

    // Written in strips of kStripRows rows, each interleaved in the file's own type first:
    // a strip's buffer is reused, where one of the whole image (75 MB for a 1080p frame's 18
    // half channels) cost its pages' first touch on every frame. OIIO's float -> half
    // conversion on writing is single-threaded (measured: 190 ms of a 1080p frame's 18
    // channels; here in parallel rows, ~10x less).
    const size_t npixels_strip = size_t(width) * size_t(std::min(height, kStripRows));
    const std::string shortfall = memory_shortfall(double(npixels_strip) * nchannels * sizeof(float),
                                                   "writing '" + path + "'", "lower the resolution");
    if (!shortfall.empty()) throw std::runtime_error(shortfall);
    std::vector<float> buffer(half ? 0 : npixels_strip * nchannels);
    std::vector<Imath::half> halves(half ? npixels_strip * nchannels : 0);

    auto out = OIIO::ImageOutput::create("openexr");  // EXR whatever the extension
    if (!out) throw std::runtime_error("cannot create EXR writer for '" + path + "': " + OIIO::geterror());
    if (!out->open(path, spec))
        throw std::runtime_error("cannot open '" + path + "' for writing: " + out->geterror());
    for (int y0 = 0; y0 < height; y0 += kStripRows) {
        const int y1 = std::min(height, y0 + kStripRows);
        parallel_for(y1 - y0, resolve_threads(0), [&](int row) {
            const size_t src0 = size_t(y0 + row) * size_t(width), dst0 = size_t(row) * size_t(width);
            for (size_t p = 0; p < passes.size(); ++p) {
                const float* rgb = passes[p].rgb;
                for (size_t i = 0; i < size_t(width); ++i)
                    for (int c = 0; c < 3; ++c) {
                        const size_t k = (dst0 + i) * nchannels + 3 * p + c;
                        const float v = rgb[3 * (src0 + i) + c];
                        if (half)
                            halves[k] = Imath::half(v);
                        else
                            buffer[k] = v;
                    }
            }
        });
        const bool written = half ? out->write_scanlines(y0, y1, 0, OIIO::TypeDesc::HALF, halves.data())
                                  : out->write_scanlines(y0, y1, 0, OIIO::TypeDesc::FLOAT, buffer.data());
        if (!written) {
            std::string err = out->geterror();
            out->close();
            throw std::runtime_error("cannot write '" + path + "': " + err);
        }
    }
    if (!out->close()) throw std::runtime_error("cannot close '" + path + "': " + out->geterror());
}

}  // namespace airlight
