// table_cache.cpp: tables on disk across processes (table_cache.h).
#include "core/table_cache.h"

#include <dlfcn.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <random>
#include <sstream>

namespace airlight {

namespace {

constexpr char kMagic[8] = {'A', 'I', 'R', 'L', 'T', 'A', 'B', '1'};

std::mutex dir_mutex;
std::string cache_dir;
bool dir_from_env_done = false;
std::atomic<long> n_built{0}, n_loaded{0}, n_refused{0};

uint64_t fnv1a(const void* bytes, size_t n, uint64_t h = 1469598103934665603ull) {
    const auto* p = static_cast<const unsigned char*>(bytes);
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

// The identity of this build: a hash of the file this code was loaded from (the Python
// module, or a test executable), once per process.
uint64_t build_id() {
    static const uint64_t id = [] {
        Dl_info info{};
        uint64_t h = 1469598103934665603ull;
        if (dladdr(reinterpret_cast<void*>(&build_id), &info) && info.dli_fname) {
            std::ifstream in(info.dli_fname, std::ios::binary);
            std::vector<char> buf(1 << 16);
            while (in) {
                in.read(buf.data(), std::streamsize(buf.size()));
                h = fnv1a(buf.data(), size_t(in.gcount()), h);
            }
        }
        return h;
    }();
    return id;
}

std::string entry_path(const std::string& dir, const std::string& key, const char* suffix = "table") {
    const uint64_t h = fnv1a(key.data(), key.size(), build_id());
    char name[40];
    std::snprintf(name, sizeof name, "%016llx.%s", static_cast<unsigned long long>(h), suffix);
    return (std::filesystem::path(dir) / name).string();
}

template <typename T>
bool read_entry(const std::string& path, const std::string& key, std::vector<T>& data, std::string& why) {
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;  // no entry: not a refusal
    char magic[8];
    uint64_t id = 0, count = 0, checksum = 0;
    uint32_t key_len = 0, elem = 0;
    in.read(magic, 8);
    in.read(reinterpret_cast<char*>(&id), 8);
    in.read(reinterpret_cast<char*>(&key_len), 4);
    if (!in || std::memcmp(magic, kMagic, 8) != 0) return why = "not an Airlight table", false;
    if (id != build_id()) return why = "written by another build", false;
    if (key_len != key.size()) return why = "another table's key", false;
    std::string stored(key_len, '\0');
    in.read(stored.data(), key_len);
    in.read(reinterpret_cast<char*>(&elem), 4);
    in.read(reinterpret_cast<char*>(&count), 8);
    if (!in || stored != key) return why = "another table's key", false;
    if (elem != sizeof(T) || count != data.size()) return why = "another table's shape", false;
    std::vector<T> values(data.size());
    in.read(reinterpret_cast<char*>(values.data()), std::streamsize(values.size() * sizeof(T)));
    in.read(reinterpret_cast<char*>(&checksum), 8);
    if (!in) return why = "truncated", false;
    if (checksum != fnv1a(values.data(), values.size() * sizeof(T))) return why = "checksum mismatch (corrupt)", false;
    if (in.peek() != std::char_traits<char>::eof()) return why = "trailing bytes", false;
    data.swap(values);
    return true;
}

template <typename T>
void write_entry(const std::string& dir, const std::string& path, const std::string& key, const std::vector<T>& data) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    std::random_device rd;
    const std::string tmp = path + "." + std::to_string(::getpid()) + "." + std::to_string(rd()) + ".tmp";
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) return;  // an unwritable cache costs the next process a build, nothing else
        const uint64_t id = build_id(), count = data.size();
        const uint32_t key_len = uint32_t(key.size()), elem = sizeof(T);
        const uint64_t checksum = fnv1a(data.data(), data.size() * sizeof(T));
        out.write(kMagic, 8);
        out.write(reinterpret_cast<const char*>(&id), 8);
        out.write(reinterpret_cast<const char*>(&key_len), 4);
        out.write(key.data(), std::streamsize(key.size()));
        out.write(reinterpret_cast<const char*>(&elem), 4);
        out.write(reinterpret_cast<const char*>(&count), 8);
        out.write(reinterpret_cast<const char*>(data.data()), std::streamsize(data.size() * sizeof(T)));
        out.write(reinterpret_cast<const char*>(&checksum), 8);
        if (!out.flush()) {
            out.close();
            std::filesystem::remove(tmp, ec);
            return;
        }
    }
    std::filesystem::rename(tmp, path, ec);
    if (ec) std::filesystem::remove(tmp, ec);
}

template <typename T>
bool load_or_build_impl(const std::string& key, std::vector<T>& data, const std::function<void()>& build) {
    const std::string dir = table_cache_dir();
    if (!dir.empty()) {
        const std::string path = entry_path(dir, key);
        std::string why;
        if (read_entry(path, key, data, why)) {
            ++n_loaded;
            return true;
        }
        if (!why.empty()) {
            ++n_refused;
            std::cerr << "Airlight: table cache file " << path << " not used (" << why << "); rebuilding it\n";
        }
        build();
        ++n_built;
        write_entry(dir, path, key, data);
        return false;
    }
    build();
    ++n_built;
    return false;
}

}  // namespace

void set_table_cache_dir(const std::string& dir) {
    std::lock_guard<std::mutex> lock(dir_mutex);
    cache_dir = dir;
    dir_from_env_done = true;
}

std::string table_cache_dir() {
    std::lock_guard<std::mutex> lock(dir_mutex);
    if (!dir_from_env_done) {
        dir_from_env_done = true;
        if (const char* env = std::getenv("AIRLIGHT_TABLE_CACHE")) cache_dir = env;
    }
    return cache_dir;
}

bool load_or_build(const std::string& key, std::vector<float>& data, const std::function<void()>& build) {
    return load_or_build_impl(key, data, build);
}

bool load_or_build(const std::string& key, std::vector<double>& data, const std::function<void()>& build) {
    return load_or_build_impl(key, data, build);
}

bool read_record(const std::string& key, std::vector<double>& data) {
    const std::string dir = table_cache_dir();
    if (dir.empty()) return false;
    const std::string path = entry_path(dir, key, "record");
    std::string why;
    if (read_entry(path, key, data, why)) return true;
    if (!why.empty()) std::cerr << "Airlight: cache file " << path << " not used (" << why << "); measuring again\n";
    return false;
}

void write_record(const std::string& key, const std::vector<double>& data) {
    const std::string dir = table_cache_dir();
    if (!dir.empty()) write_entry(dir, entry_path(dir, key, "record"), key, data);
}

TableCacheCounts table_cache_counts() { return {n_built.load(), n_loaded.load(), n_refused.load()}; }

std::string key_number(double x) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%a", x);
    return buf;
}

}  // namespace airlight
