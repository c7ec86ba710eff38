#pragma once
/// \file input_file.hpp
/// A check shared by every reader of input files.

#include <filesystem>
#include <string>
#include <system_error>

#include "sdot/error.hpp"

namespace sdot {

/// Throws InputError naming `path` when it exists but is not a regular file (or a link to one):
/// reading a device such as /dev/zero or a pipe would never end. A missing file is left to the
/// reader, whose message says it cannot be opened.
inline void require_regular_file(const std::string& path) {
  std::error_code error;
  const auto status = std::filesystem::status(path, error);
  if (!error && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status))
    throw InputError(path, std::filesystem::is_directory(status)
                               ? "is a folder, not a file"
                               : "is not a regular file (a device or a pipe cannot be read as input)");
}

}  // namespace sdot
