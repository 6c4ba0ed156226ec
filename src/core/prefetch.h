// Software prefetch of the cache lines an object occupies.
#pragma once
#include <cstddef>
#include <cstdint>

namespace relume {

inline constexpr size_t kCacheLineBytes = 64;

// Starts loading every cache line of [p, p + bytes). always_inline: GCC 12 deems a function made
// only of prefetches free of effects and deletes every call to it before inlining (docs/design/rendering.md); every
// caller that wraps it must be always_inline too.
[[gnu::always_inline]] inline void prefetchBytes(const void* p, size_t bytes) {
  const uintptr_t first = reinterpret_cast<uintptr_t>(p) & ~uintptr_t{kCacheLineBytes - 1};
  const uintptr_t last = reinterpret_cast<uintptr_t>(p) + bytes - 1;
  for (uintptr_t line = first; line <= last; line += kCacheLineBytes)
    __builtin_prefetch(reinterpret_cast<const void*>(line));
}

template <typename T>
[[gnu::always_inline]] inline void prefetchObject(const T* p) {
  prefetchBytes(p, sizeof(T));
}

}  // namespace relume
