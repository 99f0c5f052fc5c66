// memory.h: how much memory this process can still take, and the refusal of a job that
// would need more (a bake's images, the EXR writer's buffer) before it allocates any of it.
#pragma once

#include <cstddef>
#include <string>

namespace airlight {

// Bytes of memory available to this process now: the kernel's MemAvailable (/proc/meminfo:
// free memory plus the page cache it can drop), or less where a cgroup v2 memory.max caps
// the process (containers, Slurm jobs). Falls back to sysconf's free pages; SIZE_MAX when
// neither is readable (no refusal then).
size_t available_memory_bytes();

// "6.6 GB" (decimal units, as free -g and system monitors show them).
std::string format_bytes(double bytes);

// "" when _bytes_ fit in available_memory_bytes(), else the message the caller throws (a
// bake: std::invalid_argument, the EXR writer: std::runtime_error): "<what> needs about X GB
// but only Y GB of memory is available; <advice>".
std::string memory_shortfall(double bytes, const std::string& what, const std::string& advice);

}  // namespace airlight
