// sdot::write_file_atomically: outputs replace the previous file whole or not at all, even when
// the write fails or the writing process is killed, and no temporary file is left behind.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "output_file_internal.hpp"  // the named-temporary fallback (src/, private)
#include "sdot/error.hpp"
#include "sdot/output_file.hpp"
#include "support/scratch_directory.hpp"

namespace {

namespace fs = std::filesystem;
using sdot::detail::TemporaryFile;
using sdot::testing::read_text;
using sdot::testing::write_text;

// A new empty folder for one test.
fs::path fresh_folder(const std::string& name) {
  const fs::path folder = sdot::testing::scratch_directory("sdot_output_file_test") / name;
  fs::remove_all(folder);
  fs::create_directories(folder);
  return folder;
}

// The names in `folder`, sorted, hidden ones included.
std::vector<std::string> entries(const fs::path& folder) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// `size` pseudo-random bytes (every byte value, NULs included), different for each seed.
std::string bytes(std::size_t size, std::uint64_t seed) {
  std::string text(size, '\0');
  std::uint64_t state = seed * 0x9E3779B97F4A7C15ull + 1;
  for (std::size_t i = 0; i < size; ++i) {
    if (i % 8 == 0) {
      state ^= state << 13;
      state ^= state >> 7;
      state ^= state << 17;
    }
    text[i] = static_cast<char>(state >> (8 * (i % 8)));
  }
  return text;
}

mode_t permissions(const fs::path& path) {
  struct stat status {};
  EXPECT_EQ(::stat(path.c_str(), &status), 0) << path;
  return status.st_mode & 07777;
}

// Each behaviour with the O_TMPFILE temporary (the normal case on Linux) and with the named
// temporary that file systems without O_TMPFILE get.
class OutputFile : public ::testing::TestWithParam<TemporaryFile> {
 protected:
  void write(const fs::path& path, const std::string& content) {
    sdot::detail::write_file_atomically(path.string(), content, GetParam());
  }
  fs::path folder(const std::string& name) {
    return fresh_folder(name + (GetParam() == TemporaryFile::named ? "_named" : "_unnamed"));
  }
};

TEST_P(OutputFile, WritesANewFileByteExactWithTheUsualMode) {
  const fs::path dir = folder("new");
  const mode_t saved_umask = ::umask(027);
  for (const std::size_t size : {std::size_t{0}, std::size_t{1}, std::size_t{4097}, std::size_t{5} << 20}) {
    const fs::path target = dir / ("out_" + std::to_string(size) + ".bin");
    const std::string content = bytes(size, size + 1);
    write(target, content);
    EXPECT_EQ(read_text(target), content) << size;
    EXPECT_EQ(fs::file_size(target), size);
    EXPECT_EQ(permissions(target), 0640u) << "0666 & ~umask";
  }
  ::umask(saved_umask);
  EXPECT_EQ(entries(dir), (std::vector<std::string>{"out_0.bin", "out_1.bin", "out_4097.bin", "out_5242880.bin"}));
}

TEST_P(OutputFile, OverwritesAnExistingFileWholeAndKeepsItsPermissions) {
  const fs::path dir = folder("overwrite");
  const fs::path target = dir / "result.json";
  write_text(target, bytes(3 << 20, 7));
  fs::permissions(target, fs::perms::owner_read | fs::perms::owner_write);
  const std::string shorter = bytes(1000, 8);
  write(target, shorter);
  EXPECT_EQ(read_text(target), shorter) << "no tail of the longer previous content";
  EXPECT_EQ(permissions(target), 0600u);
  write(target, "");
  EXPECT_EQ(fs::file_size(target), 0u);
  const std::string longer = bytes(3 << 20, 9);
  write(target, longer);
  EXPECT_EQ(read_text(target), longer);
  EXPECT_EQ(entries(dir), std::vector<std::string>{"result.json"});
}

TEST_P(OutputFile, ARelativePathWithoutAFolderIsInTheWorkingDirectory) {
  const fs::path dir = folder("relative");
  const fs::path saved = fs::current_path();
  fs::current_path(dir);
  write("plain.txt", "text\n");
  fs::current_path(saved);
  EXPECT_EQ(read_text(dir / "plain.txt"), "text\n");
  EXPECT_EQ(entries(dir), std::vector<std::string>{"plain.txt"});
}

TEST_P(OutputFile, ANameOfTheLongestLengthStillGetsATemporaryName) {
  const fs::path dir = folder("long_name");
  const std::string name(255, 'n');  // NAME_MAX: the temporary name cuts it
  write(dir / name, "long");
  EXPECT_EQ(read_text(dir / name), "long");
  EXPECT_EQ(entries(dir), std::vector<std::string>{name});
}

TEST_P(OutputFile, ASymbolicLinkToAFileStaysAndTheFileIsReplaced) {
  const fs::path dir = folder("symlink");
  write_text(dir / "real.json", "old");
  fs::create_symlink("real.json", dir / "link.json");
  write(dir / "link.json", "new");
  EXPECT_TRUE(fs::is_symlink(dir / "link.json"));
  EXPECT_EQ(read_text(dir / "real.json"), "new");
  EXPECT_EQ(entries(dir), (std::vector<std::string>{"link.json", "real.json"}));
}

// The InputError that `write(path, ...)` throws; fails the test when there is none.
template <class Write>
std::string error_of(const fs::path& path, Write&& write) {
  try {
    write();
  } catch (const sdot::InputError& e) {
    EXPECT_EQ(e.field(), path.string());
    return e.what();
  }
  ADD_FAILURE() << "no InputError for " << path;
  return {};
}

TEST_P(OutputFile, AMissingFolderThrowsAndCreatesNothing) {
  const fs::path dir = folder("missing");
  write_text(dir / "previous.json", "previous");
  const fs::path target = dir / "no_such_folder" / "result.json";
  const std::string message = error_of(target, [&] { write(target, "new"); });
  EXPECT_EQ(message, target.string() + ": cannot write: No such file or directory");
  EXPECT_EQ(entries(dir), std::vector<std::string>{"previous.json"});
  EXPECT_EQ(read_text(dir / "previous.json"), "previous");
}

TEST_P(OutputFile, ATargetThatIsADirectoryThrowsAndChangesNothing) {
  const fs::path dir = folder("directory");
  write_text(dir / "previous.json", "previous");
  fs::create_directory(dir / "result.json");
  write_text(dir / "result.json" / "inside.txt", "inside");
  const fs::path target = dir / "result.json";
  EXPECT_EQ(error_of(target, [&] { write(target, "new"); }), target.string() + ": cannot write: Is a directory");
  const fs::path slash = dir.string() + "/previous.json/";
  EXPECT_NE(error_of(slash, [&] { write(slash, "new"); }).find("cannot write"), std::string::npos);
  EXPECT_EQ(entries(dir), (std::vector<std::string>{"previous.json", "result.json"}));
  EXPECT_EQ(read_text(dir / "previous.json"), "previous");
  EXPECT_EQ(entries(dir / "result.json"), std::vector<std::string>{"inside.txt"});
}

// A write that fails half-way (the file size limit, EFBIG) in a child process: the previous
// file is intact and the temporary is gone (the named one removed, the unnamed one never linked).
TEST_P(OutputFile, AFailureDuringTheWriteLeavesThePreviousFile) {
  const fs::path dir = folder("efbig");
  const fs::path target = dir / "result.bin";
  const std::string old_content = bytes(1000, 1);
  write_text(target, old_content);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::signal(SIGXFSZ, SIG_IGN);  // write fails with EFBIG instead of killing the process
    const rlimit limit{1 << 20, 1 << 20};
    ::setrlimit(RLIMIT_FSIZE, &limit);
    try {
      sdot::detail::write_file_atomically(target.string(), bytes(4 << 20, 2), GetParam());
    } catch (const sdot::InputError& e) {
      const bool expected = std::string(e.what()) == target.string() + ": cannot write: File too large";
      ::_exit(expected ? 0 : 10);
    } catch (...) {
      ::_exit(11);
    }
    ::_exit(12);  // no error
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "10: other message, 11: other exception, 12: no exception";
  EXPECT_EQ(read_text(target), old_content);
  EXPECT_EQ(entries(dir), std::vector<std::string>{"result.bin"});
}

INSTANTIATE_TEST_SUITE_P(Temporary, OutputFile,
                         ::testing::Values(TemporaryFile::unnamed_when_supported, TemporaryFile::named),
                         [](const ::testing::TestParamInfo<TemporaryFile>& param_info) {
                           return param_info.param == TemporaryFile::named ? std::string("Named")
                                                                           : std::string("Unnamed");
                         });

// The bytes a process `pid` has written so far to a file it holds open in `folder` (an O_TMPFILE
// file shows in /proc/PID/fd as `FOLDER/#INODE (deleted)`), or -1 when it holds none.
long long bytes_in_progress(pid_t pid, const fs::path& folder) {
  const std::string prefix = folder.string() + "/";
  std::error_code error;
  for (const auto& entry : fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", error)) {
    std::error_code link_error;
    const std::string target = fs::read_symlink(entry.path(), link_error).string();
    if (link_error || target.rfind(prefix, 0) != 0) continue;
    struct stat status {};
    if (::stat(entry.path().c_str(), &status) == 0) return static_cast<long long>(status.st_size);
  }
  return -1;
}

// Whether the file at `path` holds exactly `expected` (read in pieces: the file may be large).
bool holds(const fs::path& path, const std::string& expected) {
  std::error_code error;
  if (fs::file_size(path, error) != expected.size() || error) return false;
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) return false;
  std::vector<char> buffer(1 << 20);
  std::size_t offset = 0;
  bool same = true;
  while (same) {
    const std::size_t n = std::fread(buffer.data(), 1, buffer.size(), file);
    if (n == 0) break;
    same = offset + n <= expected.size() && std::equal(buffer.begin(), buffer.begin() + static_cast<long>(n),
                                                       expected.begin() + static_cast<long>(offset));
    offset += n;
  }
  std::fclose(file);
  return same && offset == expected.size();
}

// A writer killed with SIGKILL at various moments of a 400 MB write over an existing file: the
// file holds exactly the old or exactly the new content, and nothing else is in the folder. The
// size makes the write last well beyond the last kill (about 400 ms on the development machine,
// half of it writing and half fsync), so every kill lands before the rename.
TEST(OutputFileKilled, AKilledWriterLeavesTheOldOrTheNewFileAndNothingElse) {
  const fs::path dir = fresh_folder("killed");
  const fs::path target = dir / "result.bin";
  const std::string old_content = bytes(100000, 1);
  const std::string new_content = bytes(std::size_t{400} << 20, 2);
  constexpr int never = -1;  // the run in which the writer finishes
  int mid_write = 0;         // kills with part of the new content written, and the old file left
  for (const int delay_ms : {0, 1, 5, 20, 100, never}) {
    SCOPED_TRACE("kill after " + std::to_string(delay_ms) + " ms");
    write_text(target, old_content);
    int started[2];
    ASSERT_EQ(::pipe(started), 0);
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      ::close(started[0]);
      const char ready = 'w';
      const bool told = ::write(started[1], &ready, 1) == 1;
      try {
        sdot::write_file_atomically(target.string(), new_content);
      } catch (...) {
        ::_exit(1);
      }
      ::_exit(told ? 0 : 2);
    }
    ::close(started[1]);
    char ready = 0;
    ASSERT_EQ(::read(started[0], &ready, 1), 1);
    ::close(started[0]);
    const auto start = std::chrono::steady_clock::now();
    long long written = -1;
    if (delay_ms != never) {
      std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
      written = bytes_in_progress(child, dir);
      ::kill(child, SIGKILL);
    }
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    const double elapsed_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    const bool old_file = holds(target, old_content), new_file = !old_file && holds(target, new_content);
    EXPECT_TRUE(old_file || new_file) << "a partial or mixed file of " << fs::file_size(target) << " bytes";
    EXPECT_EQ(entries(dir), std::vector<std::string>{"result.bin"});
    if (delay_ms == never) {
      EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
      EXPECT_TRUE(new_file);
      std::printf("[ info     ] the complete 400 MB write took %.0f ms\n", elapsed_ms);
    } else {
      EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
      std::printf(
          "[ info     ] killed after %3d ms: %9lld bytes in the temporary file, the target holds the %s content\n",
          delay_ms, written,
          old_file   ? "old"
          : new_file ? "new"
                     : "WRONG");
      if (old_file && written > 0 && written < static_cast<long long>(new_content.size())) ++mid_write;
    }
  }
  std::printf("[ info     ] %d of 5 kills interrupted the write half-way\n", mid_write);
  EXPECT_GE(mid_write, 1) << "no kill landed during the write: the test checked nothing";
  fs::remove(target);
}

}  // namespace
