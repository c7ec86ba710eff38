#pragma once
// Private to the library and its tests: write_file_atomically with a choice of temporary file,
// so that the tests reach the named-temporary fallback on file systems that have O_TMPFILE.
#include <string>
#include <string_view>

namespace sdot::detail {

/// Which temporary file write_file_atomically writes to before the rename.
enum class TemporaryFile {
  unnamed_when_supported,  ///< O_TMPFILE when the system and the file system have it, else named
  named,                   ///< a hidden named file from the start (the fallback)
};

/// sdot::write_file_atomically with the temporary file `kind`.
void write_file_atomically(const std::string& path, std::string_view content, TemporaryFile kind);

}  // namespace sdot::detail
