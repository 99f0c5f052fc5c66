// memory.cpp: see memory.h.
#include "core/memory.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

#include <unistd.h>

namespace airlight {

namespace {

// The "MemAvailable:" line of /proc/meminfo in bytes, or SIZE_MAX.
size_t meminfo_available() {
    std::ifstream in("/proc/meminfo");
    std::string key;
    unsigned long long kib = 0;
    std::string unit;
    while (in >> key >> kib >> unit)
        if (key == "MemAvailable:") return size_t(kib) * 1024;
    return SIZE_MAX;
}

// One number from a cgroup v2 file of this process's group ("max" or unreadable: SIZE_MAX).
size_t cgroup_value(const std::string& group, const char* file) {
    std::ifstream in("/sys/fs/cgroup" + group + "/" + file);
    std::string text;
    if (!(in >> text) || text == "max") return SIZE_MAX;
    try {
        return size_t(std::stoull(text));
    } catch (const std::exception&) {
        return SIZE_MAX;
    }
}

// memory.max - memory.current of this process's cgroup v2 group ("0::/path" in
// /proc/self/cgroup), or SIZE_MAX where there is none or it has no limit.
size_t cgroup_available() {
    std::ifstream in("/proc/self/cgroup");
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("0::", 0) != 0) continue;
        const std::string group = line.substr(3) == "/" ? "" : line.substr(3);
        const size_t max = cgroup_value(group, "memory.max");
        if (max == SIZE_MAX) return SIZE_MAX;
        const size_t current = cgroup_value(group, "memory.current");
        return current == SIZE_MAX ? max : (max > current ? max - current : 0);
    }
    return SIZE_MAX;
}

}  // namespace

size_t available_memory_bytes() {
    size_t bytes = std::min(meminfo_available(), cgroup_available());
    if (bytes == SIZE_MAX) {
        const long pages = sysconf(_SC_AVPHYS_PAGES), page = sysconf(_SC_PAGESIZE);
        if (pages > 0 && page > 0) bytes = size_t(pages) * size_t(page);
    }
    return bytes;
}

std::string format_bytes(double bytes) {
    char text[32];
    if (bytes >= 1e9) std::snprintf(text, sizeof text, "%.1f GB", bytes / 1e9);
    else std::snprintf(text, sizeof text, "%.0f MB", bytes / 1e6);
    return text;
}

std::string memory_shortfall(double bytes, const std::string& what, const std::string& advice) {
    const size_t available = available_memory_bytes();
    if (available == SIZE_MAX || bytes <= double(available)) return "";
    return what + " needs about " + format_bytes(bytes) + " but only " + format_bytes(double(available)) +
           " of memory is available; " + advice;
}

}  // namespace airlight
