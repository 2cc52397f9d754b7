// What the fuzz targets share: a check that stops the fuzzer (a crash libFuzzer saves the
// input of) when a promise of the code under test is broken, and a scratch file for the
// readers that take a path.
#ifndef MLCLUST_FUZZ_FUZZ_CHECK_H_
#define MLCLUST_FUZZ_FUZZ_CHECK_H_

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

// Aborts with the condition and the place when `condition` is false. Unlike assert, it is
// kept in every build.
#define MLCLUST_FUZZ_CHECK(condition)                                                         \
  do {                                                                                        \
    if (!(condition)) {                                                                       \
      std::fprintf(stderr, "%s:%d: fuzz check failed: %s\n", __FILE__, __LINE__, #condition); \
      std::abort();                                                                           \
    }                                                                                         \
  } while (0)

namespace mlclust::fuzz {

// A file named `name` (its extension picks the reader) in a directory of this process's
// own under $TMPDIR, else /dev/shm, else /tmp (removed at exit), rewritten with `bytes` on every
// call; returns its path. Memory-backed /dev/shm matters: on a disk /tmp each rewrite can take
// milliseconds, many times the reader's own time.
inline std::string WriteScratchFile(std::string_view name, std::string_view bytes) {
  static const std::string directory = [] {
    const char* tmp = std::getenv("TMPDIR");
    std::string base = tmp != nullptr && *tmp != '\0'         ? tmp
                       : access("/dev/shm", W_OK | X_OK) == 0 ? "/dev/shm"
                                                              : "/tmp";
    std::string pattern = base + "/mlclust-fuzz-XXXXXX";
    if (mkdtemp(pattern.data()) == nullptr) {
      std::perror("mkdtemp");
      std::abort();
    }
    static std::string created;  // removed at exit (not after a crash, which keeps it)
    created = pattern;
    std::atexit([] { std::filesystem::remove_all(created); });
    return pattern;
  }();
  std::string path = directory + "/" + std::string(name);
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  file.close();
  MLCLUST_FUZZ_CHECK(file.good());
  return path;
}

}  // namespace mlclust::fuzz

#endif  // MLCLUST_FUZZ_FUZZ_CHECK_H_
