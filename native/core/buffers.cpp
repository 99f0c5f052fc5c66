// buffers.cpp: the pool of recycled image buffers (buffers.h).
#include "core/buffers.h"

#include <cstdint>

#ifdef __linux__
#include <sys/mman.h>
#endif

namespace airlight {

namespace {
constexpr size_t kImagePoolBytes = size_t(256) << 20;  // at most this much kept idle
constexpr size_t kImagePoolMinBytes = size_t(1) << 20;  // smaller buffers are not worth keeping
struct ImagePool {
    std::mutex mutex;
    std::vector<std::vector<float>> buffers;  // oldest first
    size_t bytes = 0;
};
ImagePool& image_pool() {
    static ImagePool* pool = new ImagePool;  // never destroyed: numpy may free arrays at exit
    return *pool;
}

// A buffer of capacity >= n: a held one of at most twice that (warm pages), else new memory that
// no one has touched yet, on transparent huge pages where the kernel allows.
std::vector<float> take_image_buffer(size_t n) {
    std::vector<float> taken;
    {
        ImagePool& pool = image_pool();
        std::lock_guard<std::mutex> lock(pool.mutex);
        // The smallest buffer that holds n floats, if it is not more than twice that.
        size_t best = pool.buffers.size();
        for (size_t i = 0; i < pool.buffers.size(); ++i) {
            const size_t c = pool.buffers[i].capacity();
            if (c >= n && c / 2 <= n && (best == pool.buffers.size() || c < pool.buffers[best].capacity())) best = i;
        }
        if (best < pool.buffers.size()) {
            taken = std::move(pool.buffers[best]);
            pool.buffers.erase(pool.buffers.begin() + std::ptrdiff_t(best));
            pool.bytes -= taken.capacity() * sizeof(float);
        }
    }
    if (taken.capacity() >= n) return taken;
    taken.clear();
    taken.shrink_to_fit();
    taken.reserve(n);  // allocates without touching the pages
#ifdef __linux__
    const uintptr_t huge = uintptr_t(2) << 20;
    const uintptr_t begin = (reinterpret_cast<uintptr_t>(taken.data()) + huge - 1) & ~(huge - 1);
    const uintptr_t end = (reinterpret_cast<uintptr_t>(taken.data() + n)) & ~(huge - 1);
    if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#endif
    return taken;
}
}  // namespace

void acquire_image_buffer(std::vector<float>& v, size_t n, float value) {
    v = take_image_buffer(n);
    v.assign(n, value);  // within capacity: no reallocation
}

void acquire_image_copy(std::vector<float>& v, const std::vector<float>& from) {
    v = take_image_buffer(from.size());
    v.assign(from.begin(), from.end());
}

void recycle_image_buffer(std::vector<float>&& buffer) {
    const size_t bytes = buffer.capacity() * sizeof(float);
    if (bytes < kImagePoolMinBytes || bytes > kImagePoolBytes) return;  // freed by the caller's vector
    std::vector<std::vector<float>> evicted;  // freed outside the lock
    ImagePool& pool = image_pool();
    std::lock_guard<std::mutex> lock(pool.mutex);
    while (!pool.buffers.empty() && pool.bytes + bytes > kImagePoolBytes) {
        pool.bytes -= pool.buffers.front().capacity() * sizeof(float);
        evicted.push_back(std::move(pool.buffers.front()));
        pool.buffers.erase(pool.buffers.begin());
    }
    pool.bytes += bytes;
    pool.buffers.push_back(std::move(buffer));
}

}  // namespace airlight
