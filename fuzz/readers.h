// The files relume reads from users or from earlier runs, each behind one entry point "read
// these bytes as that file and touch what its consumers index". Shared by the libFuzzer
// harnesses (fuzz/fuzz_<reader>.cpp) and the corpus-replay test (tests/fuzz), so a crash the
// fuzzer found stays a test.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace relume::fuzz {

// Reader names; each is also its corpus folder, tests/data/fuzz/<name>/.
std::vector<std::string> readerNames();

// Writes `data` to a scratch file of the reader's kind (per process, next to the files it refers
// to) and reads it. Bad input must end in relume::Error, which is swallowed; anything else (another
// exception, a crash, a sanitizer report) escapes. Throws std::invalid_argument on an unknown reader.
void readBytes(const std::string& reader, const uint8_t* data, size_t size);

}  // namespace relume::fuzz
