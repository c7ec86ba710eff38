#pragma once
// Test support shared by the command tests (sdot, sdot-sphere-param, sdot-blue-noise): a
// per-process scratch directory, removed when the test process exits, and whole-file text I/O.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace sdot::testing {

/// `<temp>/<prefix>_<pid>`, created on the first call and removed at exit.
inline const std::filesystem::path& scratch_directory(const std::string& prefix) {
  struct Directory {
    std::filesystem::path path;
    ~Directory() {
      std::error_code ignored;
      std::filesystem::remove_all(path, ignored);
    }
  };
  static const Directory directory{[&] {
    auto path = std::filesystem::temp_directory_path() / (prefix + "_" + std::to_string(::getpid()));
    std::filesystem::create_directories(path);
    return path;
  }()};
  return directory.path;
}

inline std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

}  // namespace sdot::testing
