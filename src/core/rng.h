// PCG32 (O'Neill 2014) seeded from a hash of a tuple, never from the thread,
// so any sample can be reproduced alone and results do not depend on scheduling.
#pragma once
#include <cstdint>
#include <initializer_list>

#include "core/math.h"

namespace relume {

inline uint64_t mix64(uint64_t z) {  // splitmix64 finaliser
  z += 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

inline uint64_t hashTuple(std::initializer_list<uint64_t> parts) {
  uint64_t h = 0x243f6a8885a308d3ull;
  for (uint64_t p : parts) h = mix64(h ^ mix64(p));
  return h;
}

class Pcg32 {
 public:
  Pcg32() { seed(0); }
  explicit Pcg32(uint64_t key) { seed(key); }
  // Both state and stream come from the key: streams chosen by increment alone are correlated.
  void seed(uint64_t key) {
    state_ = 0u;
    inc_ = (mix64(key ^ 0xda3e39cb94b95bdbull) << 1u) | 1u;
    nextU32();
    state_ += mix64(key);
    nextU32();
  }
  uint32_t nextU32() {
    const uint64_t old = state_;
    state_ = old * 6364136223846793005ull + inc_;
    const uint32_t xorshifted = static_cast<uint32_t>(((old >> 18u) ^ old) >> 27u);
    const uint32_t rot = static_cast<uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31));
  }
  // Uniform in [0,1): 24 random mantissa bits, never returns 1.
  float next1D() { return static_cast<float>(nextU32() >> 8) * 0x1p-24f; }
  // Two or three draws as a point, the last coordinate drawn first: the order GCC gave
  // `Vec2(next1D(), next1D())` (C++ leaves the order of arguments unspecified), kept so that every
  // stream stays what it was, now whatever the compiler.
  Vec2 next2D() {
    const float y = next1D();
    return {next1D(), y};
  }
  Vec3 next3D() {
    const float z = next1D(), y = next1D();
    return {next1D(), y, z};
  }

 private:
  uint64_t state_ = 0, inc_ = 1;
};

}  // namespace relume
