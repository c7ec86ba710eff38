#include "sdot/output_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <random>

#include "output_file_internal.hpp"
#include "sdot/error.hpp"

namespace sdot {
namespace {

// A failed system call, with its errno; becomes an InputError naming the path at the top.
struct SystemFailure {
  int error;
};

[[noreturn]] void fail(int error) {
  throw SystemFailure{error};
}

// An open file descriptor, closed on destruction.
class Descriptor {
 public:
  explicit Descriptor(int fd) : fd_(fd) {}
  Descriptor(const Descriptor&) = delete;
  Descriptor& operator=(const Descriptor&) = delete;
  ~Descriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  [[nodiscard]] int get() const { return fd_; }

 private:
  int fd_;
};

// A temporary file name in the folder, removed on destruction unless released.
class TemporaryName {
 public:
  explicit TemporaryName(int dir) : dir_(dir) {}
  TemporaryName(const TemporaryName&) = delete;
  TemporaryName& operator=(const TemporaryName&) = delete;
  ~TemporaryName() {
    if (!name_.empty()) ::unlinkat(dir_, name_.c_str(), 0);
  }
  void set(std::string name) { name_ = std::move(name); }
  [[nodiscard]] const std::string& name() const { return name_; }
  void release() { name_.clear(); }

 private:
  int dir_;
  std::string name_;
};

// `.NAME.XXXXXX.tmp` with six random letters or digits; NAME is cut so that the whole fits NAME_MAX.
std::string temporary_name(const std::string& name) {
  static std::atomic<std::uint64_t> counter{0};
  static constexpr char letters[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789";
  // Unpredictable enough to avoid collisions (which O_EXCL and linkat's EEXIST catch anyway).
  std::seed_seq seed{static_cast<std::uint64_t>(::getpid()), counter++,
                     static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count()),
                     static_cast<std::uint64_t>(std::chrono::system_clock::now().time_since_epoch().count())};
  std::mt19937_64 random(seed);
  std::string result(1, '.');
  result.append(name, 0, 200).push_back('.');
  for (int i = 0; i < 6; ++i) result.push_back(letters[random() % (sizeof letters - 1)]);
  return result.append(".tmp");
}

void write_all(int fd, std::string_view content) {
  const char* data = content.data();
  std::size_t left = content.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, data, std::min<std::size_t>(left, std::size_t{1} << 30));
    if (n < 0) {
      if (errno == EINTR) continue;
      fail(errno);
    }
    if (n == 0) fail(EIO);
    data += n;
    left -= static_cast<std::size_t>(n);
  }
}

void sync(int fd) {
  while (::fsync(fd) != 0)
    if (errno != EINTR) fail(errno);
}

#ifdef O_TMPFILE
// An unnamed file in the folder, or -1 when the file system does not support O_TMPFILE.
int open_unnamed(int dir) {
  for (;;) {
    const int fd = ::openat(dir, ".", O_TMPFILE | O_WRONLY | O_CLOEXEC, 0666);
    if (fd >= 0) return fd;
    if (errno == EINTR) continue;
    if (errno == EOPNOTSUPP || errno == EISDIR || errno == EINVAL) return -1;
    fail(errno);
  }
}

// Gives the unnamed file `fd` the name `name` in the folder; false when the name exists.
bool link_unnamed(int fd, int dir, const std::string& name) {
  const std::string proc = "/proc/self/fd/" + std::to_string(fd);
  if (::linkat(AT_FDCWD, proc.c_str(), dir, name.c_str(), AT_SYMLINK_FOLLOW) == 0) return true;
  const int error = errno;
  if (error == EEXIST) return false;
#ifdef AT_EMPTY_PATH
  if (error == ENOENT) {  // no /proc: AT_EMPTY_PATH (which may need CAP_DAC_READ_SEARCH)
    if (::linkat(fd, "", dir, name.c_str(), AT_EMPTY_PATH) == 0) return true;
    if (errno == EEXIST) return false;
  }
#endif
  fail(error);
}
#endif

// A new hidden file in the folder, named in `temporary`.
int open_named(int dir, const std::string& name, TemporaryName& temporary) {
  for (int attempt = 0; attempt < 100; ++attempt) {
    std::string candidate = temporary_name(name);
    const int fd = ::openat(dir, candidate.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      temporary.set(std::move(candidate));
      return fd;
    }
    if (errno != EEXIST && errno != EINTR) fail(errno);
  }
  fail(EEXIST);
}

void write_atomically(std::string target, std::string_view content, detail::TemporaryFile kind) {
  if (target.empty()) fail(ENOENT);
  // A symbolic link to a file: replace that file, as writing through the link would.
  struct stat status {};
  if (::lstat(target.c_str(), &status) == 0 && S_ISLNK(status.st_mode)) {
    if (char* resolved = ::realpath(target.c_str(), nullptr)) {
      target = resolved;
      std::free(resolved);
    }
  }
  const std::size_t slash = target.rfind('/');
  const std::string folder = slash == std::string::npos ? std::string(".")
                             : slash == 0               ? std::string("/")
                                                        : target.substr(0, slash);
  const std::string name = slash == std::string::npos ? target : target.substr(slash + 1);
  if (name.empty() || name == "." || name == "..") fail(EISDIR);

  Descriptor dir(::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir.get() < 0) fail(errno);
  // Refuse a directory before writing anything; keep a replaced file's permission bits.
  mode_t keep_mode = 0;
  bool keep = false;
  if (::fstatat(dir.get(), name.c_str(), &status, AT_SYMLINK_NOFOLLOW) == 0) {
    if (S_ISDIR(status.st_mode)) fail(EISDIR);
    keep = S_ISREG(status.st_mode);
    keep_mode = status.st_mode & 0777;
  }

  TemporaryName temporary(dir.get());  // removed on every failure below
  int fd = -1;
#ifdef O_TMPFILE
  const bool unnamed = kind == detail::TemporaryFile::unnamed_when_supported && (fd = open_unnamed(dir.get())) >= 0;
#else
  const bool unnamed = false;
  (void)kind;
#endif
  if (!unnamed) fd = open_named(dir.get(), name, temporary);
  Descriptor file(fd);
  if (keep) (void)::fchmod(file.get(), keep_mode);  // best effort: some file systems refuse
  write_all(file.get(), content);
  sync(file.get());
#ifdef O_TMPFILE
  if (unnamed) {
    for (int attempt = 0;; ++attempt) {
      std::string candidate = temporary_name(name);
      if (link_unnamed(file.get(), dir.get(), candidate)) {
        temporary.set(std::move(candidate));
        break;
      }
      if (attempt == 100) fail(EEXIST);
    }
  }
#endif
  // From the link to the rename (two system calls) the temporary file has a name: the one moment
  // at which a killed process leaves it behind. The descriptor closes after the rename (fsync has
  // reported any write error).
  if (::renameat(dir.get(), temporary.name().c_str(), dir.get(), name.c_str()) != 0) fail(errno);
  temporary.release();
  // Make the rename itself durable; some file systems cannot sync a folder (EINVAL).
  while (::fsync(dir.get()) != 0)
    if (errno != EINTR) {
      if (errno == EINVAL) break;
      fail(errno);
    }
}

}  // namespace

namespace detail {

void write_file_atomically(const std::string& path, std::string_view content, TemporaryFile kind) {
  try {
    write_atomically(path, content, kind);
  } catch (const SystemFailure& failure) {
    throw InputError(path, std::string("cannot write: ") + std::strerror(failure.error));
  }
}

}  // namespace detail

void write_file_atomically(const std::string& path, std::string_view content) {
  detail::write_file_atomically(path, content, detail::TemporaryFile::unnamed_when_supported);
}

}  // namespace sdot
