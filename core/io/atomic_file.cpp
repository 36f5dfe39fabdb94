#include <spacewarp/core/io/atomic_file.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>
#include <streambuf>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include <spacewarp/core/errors.h>

namespace spacewarp {
namespace {

namespace fs = std::filesystem;

std::string quoted(const fs::path& path) {
  std::string text(1, '\'');
  text += path.string();
  text += '\'';
  return text;
}

[[noreturn]] void fail(const fs::path& path, const std::string& reason) {
  throw IoError("cannot write " + quoted(path) + ": " + reason);
}

/// A hard-to-guess suffix: random bits, a process-wide counter and the time, so that
/// concurrent writers (threads or processes) practically never collide. Collisions that do
/// happen are caught by the exclusive create and retried.
std::string uniqueSuffix() {
  static std::atomic<std::uint64_t> counter{0};
  thread_local std::mt19937_64 rng{[] {
    std::random_device device;
    return (static_cast<std::uint64_t>(device()) << 32) ^ device();
  }()};
  const std::uint64_t bits =
      rng() ^ counter.fetch_add(1, std::memory_order_relaxed) ^
      static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
  char buffer[17];
  std::snprintf(buffer, sizeof buffer, "%016llx", static_cast<unsigned long long>(bits));
  return buffer;
}

// The list of live temporaries that removeAtomicTemporaries() reads from a signal handler: a
// fixed array (no allocation, no locks) whose slots are claimed and released with lock-free
// atomics. A slot's path is only written while its state is kFilling, so the handler never
// reads a path that is being changed.
enum SlotState : int { kFree, kFilling, kListed, kRemoving, kRemoved };
constexpr std::size_t kSlotCount = 64;
constexpr std::size_t kSlotPathSize = 4096;
static_assert(std::atomic<int>::is_always_lock_free);

struct Slot {
  std::atomic<int> state{kFree};
  char path[kSlotPathSize];
};
Slot slots[kSlotCount];

/// Lists `path` and returns its slot, or -1 if it is too long or every slot is taken.
int listTemporary(const std::string& path) {
  if (path.size() >= kSlotPathSize) return -1;
  for (std::size_t i = 0; i < kSlotCount; ++i) {
    int expected = kFree;
    if (slots[i].state.compare_exchange_strong(expected, kFilling, std::memory_order_acquire)) {
      std::memcpy(slots[i].path, path.c_str(), path.size() + 1);
      slots[i].state.store(kListed, std::memory_order_release);
      return static_cast<int>(i);
    }
  }
  return -1;
}

void unlistTemporary(int slot) {
  if (slot < 0) return;
  std::atomic<int>& state = slots[slot].state;
  for (;;) {
    int expected = kListed;
    if (state.compare_exchange_strong(expected, kFree, std::memory_order_acq_rel)) return;
    if (expected == kRemoved) {
      state.store(kFree, std::memory_order_release);
      return;
    }
    std::this_thread::yield();  // kRemoving: a handler on another thread is unlinking it
  }
}

/// A new, empty temporary file beside the target, created exclusively (so it did not exist
/// before), listed for removeAtomicTemporaries() before it exists, and unlinked on
/// destruction unless renamed into place.
class Temporary {
 public:
  explicit Temporary(const fs::path& target) {
    const fs::path directory = target.parent_path();
    std::string stem(1, '.');
    stem += target.filename().string();
    stem += '.';
    for (int attempt = 0; attempt < 100; ++attempt) {
      path_ = directory / (stem + uniqueSuffix() + ".tmp");
      // The handler must find it by this name whatever the working directory is by then.
      std::error_code ignored;
      const fs::path absolute = fs::absolute(path_, ignored);
      slot_ = listTemporary(absolute.empty() ? path_.string() : absolute.string());
      fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
      if (fd_ >= 0) return;
      const int error = errno;
      unlistTemporary(slot_);
      slot_ = -1;
      if (error != EEXIST) {
        fail(target, "cannot create a temporary file in " +
                         quoted(directory.empty() ? fs::path(".") : directory) + ": " +
                         std::strerror(error));
      }
    }
    fail(target, "no unique temporary file name found");
  }
  Temporary(const Temporary&) = delete;
  Temporary& operator=(const Temporary&) = delete;
  ~Temporary() {
    if (fd_ >= 0) ::close(fd_);
    if (!renamed_) ::unlink(path_.c_str());
    unlistTemporary(slot_);
  }

  int fd() const { return fd_; }
  const fs::path& path() const { return path_; }
  /// Closes the descriptor; returns errno of a failed close, or 0.
  int close() {
    const int result = ::close(fd_);
    fd_ = -1;
    return result == 0 ? 0 : errno;
  }
  void renamed() { renamed_ = true; }

 private:
  fs::path path_;
  int fd_ = -1;
  int slot_ = -1;
  bool renamed_ = false;
};

/// An output stream buffer over a file descriptor that checks every write and keeps the
/// first error's errno, so that the failure reported is the system's (a full disk, a file
/// size limit) rather than a bare "stream failed". Seekable, as OpenVDB's writer needs.
class DescriptorBuffer : public std::streambuf {
 public:
  explicit DescriptorBuffer(int fd) : fd_(fd), buffer_(kBufferSize) { resetBuffer(); }

  /// errno of the first failed operation, or 0.
  int error() const { return error_; }

 protected:
  int_type overflow(int_type ch) override {
    if (!flushBuffer()) return traits_type::eof();
    if (!traits_type::eq_int_type(ch, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(ch);
      pbump(1);
    }
    return traits_type::not_eof(ch);
  }

  std::streamsize xsputn(const char* data, std::streamsize count) override {
    if (count <= epptr() - pptr()) {
      std::memcpy(pptr(), data, static_cast<std::size_t>(count));
      pbump(static_cast<int>(count));
      return count;
    }
    // Larger than the room left: flush and write it straight through.
    if (!flushBuffer() || !writeAll(data, static_cast<std::size_t>(count))) return 0;
    return count;
  }

  int sync() override { return flushBuffer() ? 0 : -1; }

  pos_type seekoff(off_type offset, std::ios_base::seekdir direction,
                   std::ios_base::openmode which) override {
    if (!(which & std::ios_base::out) || !flushBuffer()) return pos_type(off_type(-1));
    const int whence = direction == std::ios_base::beg   ? SEEK_SET
                       : direction == std::ios_base::cur ? SEEK_CUR
                                                         : SEEK_END;
    const off_t result = ::lseek(fd_, static_cast<off_t>(offset), whence);
    if (result < 0) {
      error_ = errno;
      return pos_type(off_type(-1));
    }
    return pos_type(static_cast<off_type>(result));
  }

  pos_type seekpos(pos_type position, std::ios_base::openmode which) override {
    return seekoff(off_type(position), std::ios_base::beg, which);
  }

 private:
  static constexpr std::size_t kBufferSize = 1 << 16;

  void resetBuffer() { setp(buffer_.data(), buffer_.data() + buffer_.size()); }

  bool flushBuffer() {
    if (error_ != 0) return false;
    const bool ok = writeAll(pbase(), static_cast<std::size_t>(pptr() - pbase()));
    resetBuffer();
    return ok;
  }

  bool writeAll(const char* data, std::size_t count) {
    if (error_ != 0) return false;
    while (count > 0) {
      const ssize_t written = ::write(fd_, data, count);
      if (written < 0) {
        if (errno == EINTR) continue;
        error_ = errno;
        return false;
      }
      if (written == 0) {
        error_ = EIO;
        return false;
      }
      data += written;
      count -= static_cast<std::size_t>(written);
    }
    return true;
  }

  int fd_;
  std::vector<char> buffer_;
  int error_ = 0;
};

/// Makes the rename durable. Failures are ignored: the new file is already in place and
/// complete, and some file systems cannot sync a directory at all.
void syncDirectory(const fs::path& directory) {
  const int fd =
      ::open(directory.empty() ? "." : directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

}  // namespace

namespace {

// The file a chain of symbolic links ends at (itself when `path` is no link), so that writing
// "through" a link replaces the file it names, as a plain open() would, and leaves the link.
std::filesystem::path linkTarget(const std::filesystem::path& path) {
  std::filesystem::path target = path;
  for (int hop = 0; hop < 40; ++hop) {  // 40: the kernel's own limit on link chains
    std::error_code error;
    if (!std::filesystem::is_symlink(std::filesystem::symlink_status(target, error))) return target;
    const std::filesystem::path next = std::filesystem::read_symlink(target, error);
    if (error) fail(path, "cannot read the symbolic link: " + error.message());
    target = next.is_absolute() ? next : target.parent_path() / next;
  }
  fail(path, "too many levels of symbolic links");
}

}  // namespace

void writeFileAtomically(const std::filesystem::path& requested,
                         const std::function<void(std::ostream&)>& write) {
  if (requested.filename().empty() || requested.filename() == "." || requested.filename() == "..")
    fail(requested, "not a file name");
  const std::filesystem::path path = linkTarget(requested);

  struct stat old {};
  const bool replacing = ::stat(path.c_str(), &old) == 0 && S_ISREG(old.st_mode);

  Temporary temporary(path);
  if (replacing && ::fchmod(temporary.fd(), old.st_mode & 07777) != 0)
    fail(path, std::string("cannot give the new file the old one's permissions: ") +
                   std::strerror(errno));
  {
    DescriptorBuffer buffer(temporary.fd());
    std::ostream out(&buffer);
    try {
      write(out);
    } catch (...) {
      // A writer that throws because its stream failed: report the system's reason.
      if (buffer.error() != 0) fail(path, std::strerror(buffer.error()));
      throw;  // the temporary's destructor removes it
    }
    out.flush();
    if (buffer.error() != 0) fail(path, std::strerror(buffer.error()));
    if (!out) fail(path, "write failed");
  }
  // EINVAL/ENOTSUP: a file system without sync (the data is as durable as it gets there).
  if (::fsync(temporary.fd()) != 0 && errno != EINVAL && errno != ENOTSUP)
    fail(path, std::string("cannot sync to disk: ") + std::strerror(errno));
  if (const int error = temporary.close(); error != 0)
    fail(path, std::string("closing the file failed: ") + std::strerror(error));
  if (::rename(temporary.path().c_str(), path.c_str()) != 0) fail(path, std::strerror(errno));
  temporary.renamed();
  syncDirectory(path.parent_path());
}

void removeAtomicTemporaries() noexcept {
  for (Slot& slot : slots) {
    int expected = kListed;
    if (slot.state.compare_exchange_strong(expected, kRemoving, std::memory_order_acquire)) {
      ::unlink(slot.path);
      slot.state.store(kRemoved, std::memory_order_release);
    }
  }
}

}  // namespace spacewarp
