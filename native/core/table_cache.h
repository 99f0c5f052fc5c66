// table_cache.h: the models' tables (Sun 2005's F, the surface G grids, Biri 2006's Gamma,
// the sun-glow tables) kept on disk across processes, so that a farm's per-frame `blender -b
// -f N` does not rebuild them every frame.
//
// An entry is one file <dir>/<hash>.table holding a magic, the build's identity (a hash of
// the native module's own file: any rebuild invalidates every entry), the table's key (its
// kind and parameters, spelled out by the caller), the element size and count, the values and
// their checksum. A file that does not match in every field, is truncated or fails its
// checksum is never used: the table is rebuilt with a note on stderr and the entry rewritten.
// Entries are written to a temporary file in the same folder and renamed over the entry
// (atomic on POSIX), so processes that build one table at once each write a whole file and
// readers see the old or the new one, never a mix.
//
// The cache is off until a folder is set (set_table_cache_dir, or $AIRLIGHT_TABLE_CACHE at
// the first use); the add-on sets the user's cache folder.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace airlight {

// The folder ("" turns the cache off). Created on the first write. Thread safe.
void set_table_cache_dir(const std::string& dir);
std::string table_cache_dir();

// _data_ (sized by the caller to the table's shape) from the entry of _key_, or filled by
// _build_ and stored. Returns true when it was read from the cache. Thread safe.
bool load_or_build(const std::string& key, std::vector<float>& data, const std::function<void()>& build);
bool load_or_build(const std::string& key, std::vector<double>& data, const std::function<void()>& build);

// A measured record under _key_ (a choice that took bakes to make, kept so that the same
// scene is not measured again: the add-on's soft-shadow probe), in <dir>/<hash>.record with
// the same checks, and not counted as a table. read_record fills _data_ (sized by the caller)
// and returns true from a valid entry; a refused file gets the note on stderr.
bool read_record(const std::string& key, std::vector<double>& data);
void write_record(const std::string& key, const std::vector<double>& data);

// Per process: tables built (the cache missed or is off), read from the cache, and cache
// files refused (corrupt, truncated or foreign).
struct TableCacheCounts {
    long built = 0, loaded = 0, refused = 0;
};
TableCacheCounts table_cache_counts();

// A key's parameters, printed exactly (hex floats), for the callers' keys.
std::string key_number(double x);

}  // namespace airlight
