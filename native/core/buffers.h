// buffers.h: the bake's memory kept warm between bakes: output images and per-thread scratch.
#pragma once

#include <cstddef>
#include <memory>
#include <mutex>
#include <vector>

namespace airlight {

// Images and tables on recycled memory. Fresh pages cost ~10-20 us per 4 KiB page fault on
// the development machine (a 1080p bake's 60 MB of passes: ~100-200 ms, more than the bake
// itself), so the bindings hand an output buffer back with recycle_image_buffer when numpy
// frees it, as the bake's own large temporaries do when they end (a light-depth map, the
// refinement's copy of the splat's image), and acquire_image_buffer gives the next ones those
// warm pages (a held buffer of 1 to 2 times the size asked for; else new memory, on
// transparent huge pages where the kernel allows). At most 256 MB are kept, oldest dropped
// first. Thread safe.
// acquire_image_buffer: _v_ = _n_ copies of _value_.
void acquire_image_buffer(std::vector<float>& v, size_t n, float value);
// _v_ = a copy of _from_, on recycled memory.
void acquire_image_copy(std::vector<float>& v, const std::vector<float>& from);
void recycle_image_buffer(std::vector<float>&& buffer);

// Sizes _v_ to _n_ zeros (acquire_image_buffer).
inline void allocate_image(std::vector<float>& v, size_t n) { acquire_image_buffer(v, n, 0.0f); }

// Scratch objects kept between bands and between bakes, one per concurrent user: fresh
// pages cost ~10-20 us per 4 KiB fault here (acquire_image_buffer), more than a band's work
// when its scratch runs to megabytes. A Lease takes one (or a new one) and gives it back.
template <typename T>
class ScratchPool {
  public:
    class Lease {
      public:
        explicit Lease(ScratchPool& pool) : pool_(pool) {
            {
                std::lock_guard<std::mutex> lock(pool_.mutex_);
                if (!pool_.free_.empty()) item_ = std::move(pool_.free_.back()), pool_.free_.pop_back();
            }
            if (!item_) item_ = std::make_unique<T>();
        }
        ~Lease() {
            std::lock_guard<std::mutex> lock(pool_.mutex_);
            pool_.free_.push_back(std::move(item_));
        }
        Lease(const Lease&) = delete;
        Lease& operator=(const Lease&) = delete;
        T& operator*() { return *item_; }

      private:
        ScratchPool& pool_;
        std::unique_ptr<T> item_;
    };

  private:
    std::mutex mutex_;
    std::vector<std::unique_ptr<T>> free_;
};

}  // namespace airlight
