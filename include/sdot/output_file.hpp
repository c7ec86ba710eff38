#pragma once
/// \file output_file.hpp
/// Writing an output file so that nothing is lost: a reader, a crash or a killed process sees
/// either the previous file or the complete new one, never a partial file.

#include <string>
#include <string_view>

namespace sdot {

/// Replaces the file at `path` with `content`, atomically: the content goes to a temporary file
/// in the same folder, which is flushed to disk (fsync) and then renamed over `path`; the
/// folder is flushed after the rename. At every moment `path` holds either its previous content
/// (or does not exist, if it did not) or the complete `content`.
///
/// On Linux the temporary file is an unnamed O_TMPFILE file, so a process killed while writing
/// leaves nothing behind; it gets a hidden name (`.NAME.XXXXXX.tmp`) only for the moment
/// between the end of the write and the rename. On file systems without O_TMPFILE (and other
/// systems) the temporary file is named from the start and removed on every failure, but a
/// process killed during the write leaves it behind.
///
/// A new file gets the mode 0666 & ~umask; a replaced regular file keeps its permission bits
/// (when the file system allows it). When `path` is a symbolic link to a file, the file it
/// points to is replaced and the link stays. The folder must exist (it is not created).
///
/// \param path     the file to create or replace.
/// \param content  the bytes to write (binary, written as they are).
/// \throws InputError whose field is `path` and whose message is `cannot write: <reason>`
///   (the system's error text, e.g. "No such file or directory" for a missing folder, "Is a
///   directory", "No space left on device") when the file cannot be written. Then the
///   previous file at `path` is untouched and no temporary file is left. The one exception is a
///   failure to flush the folder after the rename: the new content is then in place, but may
///   not survive a power loss, and the error is still thrown.
void write_file_atomically(const std::string& path, std::string_view content);

}  // namespace sdot
