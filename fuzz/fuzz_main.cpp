// libFuzzer entry point, built once per reader as fuzz_<reader> with RELUME_FUZZ_READER="<reader>"
// (fuzz/CMakeLists.txt); the reader itself is a row of readers.cpp.
#include "readers.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  relume::fuzz::readBytes(RELUME_FUZZ_READER, data, size);
  return 0;
}
