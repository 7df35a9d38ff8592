// FNV-1a, 64 bit (Fowler, Noll, Vo; the published offset basis and prime): the library's one byte
// hash. Used where a cheap fingerprint of bytes is enough: recomputed trajectory states
// (hashState) and the content hashes of the results file (problems/topopt/results_file.h).
//
// What it is good for: detecting corruption. Each byte step (xor, then multiply by an odd prime
// modulo 2^64) is a bijection of the 64-bit state, so changing any single byte always changes the
// hash, and a random change goes unnoticed with probability 2^-64. What it is not: a protection
// against deliberate tampering; anyone can recompute it. It is hand-written because it is eight
// lines and needs no dependency (the engine depends on Eigen only).
#pragma once

#include <cstddef>
#include <cstdint>

namespace hindsight {

inline constexpr std::uint64_t kFnv1aOffsetBasis = 14695981039346656037ULL;

/// Continues the hash `h` over `size` bytes at `data`; start with kFnv1aOffsetBasis.
std::uint64_t fnv1a(const void* data, std::size_t size, std::uint64_t h = kFnv1aOffsetBasis);

}  // namespace hindsight
