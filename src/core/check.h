// Invariants of the code (not of the input: bad input is a relume::Error). CHECK is always on and
// aborts with the failed condition and its place; DCHECK only in builds without NDEBUG.
#pragma once
#include <cstdio>
#include <cstdlib>

#define RELUME_CHECK_FAILED(text) \
  (std::fprintf(stderr, "relume: internal check failed: %s at %s:%d\n", text, __FILE__, __LINE__), std::abort())
#define CHECK(cond) ((cond) ? (void)0 : RELUME_CHECK_FAILED(#cond))
#define CHECK_EQ(a, b) CHECK((a) == (b))
#ifdef NDEBUG
#define DCHECK(cond) ((void)0)
#else
#define DCHECK(cond) CHECK(cond)
#endif
