#include <spacewarp/core/io/atomic_file.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
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

// Folders of writeFolderAtomically(): the temporary folder, or the old folder while it is
// swapped out by two renames, with the place it goes back to (`restore`, "" if none).
constexpr std::size_t kFolderSlotCount = 8;

struct FolderSlot {
  std::atomic<int> state{kFree};
  char path[kSlotPathSize];
  char restore[kSlotPathSize];
};
FolderSlot folderSlots[kFolderSlotCount];

/// Claims a free slot of `table` and lets `fill` write its paths; returns it, or -1 if every
/// slot is taken.
template <typename SlotT, std::size_t N, typename Fill>
int claimSlot(SlotT (&table)[N], const Fill& fill) {
  for (std::size_t i = 0; i < N; ++i) {
    int expected = kFree;
    if (table[i].state.compare_exchange_strong(expected, kFilling, std::memory_order_acquire)) {
      fill(table[i]);
      table[i].state.store(kListed, std::memory_order_release);
      return static_cast<int>(i);
    }
  }
  return -1;
}

template <typename SlotT, std::size_t N>
void releaseSlot(SlotT (&table)[N], int slot) {
  if (slot < 0) return;
  std::atomic<int>& state = table[slot].state;
  for (;;) {
    int expected = kListed;
    if (state.compare_exchange_strong(expected, kFree, std::memory_order_acq_rel)) return;
    if (expected == kRemoved) {
      state.store(kFree, std::memory_order_release);
      return;
    }
    std::this_thread::yield();  // kRemoving: a handler on another thread is removing it
  }
}

/// Lists `path` and returns its slot, or -1 if it is too long or every slot is taken.
int listTemporary(const std::string& path) {
  if (path.size() >= kSlotPathSize) return -1;
  return claimSlot(slots,
                   [&](Slot& slot) { std::memcpy(slot.path, path.c_str(), path.size() + 1); });
}

void unlistTemporary(int slot) { releaseSlot(slots, slot); }

/// Lists the folder `path` (to be put back at `restore` if that is not empty and nothing is
/// there, removed otherwise); returns its slot or -1.
int listFolder(const std::string& path, const std::string& restore) {
  if (path.size() >= kSlotPathSize || restore.size() >= kSlotPathSize) return -1;
  return claimSlot(folderSlots, [&](FolderSlot& slot) {
    std::memcpy(slot.path, path.c_str(), path.size() + 1);
    std::memcpy(slot.restore, restore.c_str(), restore.size() + 1);
  });
}

void unlistFolder(int slot) { releaseSlot(folderSlots, slot); }

/// Removes the entries of the folder `path` (files, links, empty folders), then the folder.
/// Async-signal-safe: system calls only (getdents64 rather than readdir, which allocates).
void removeFolderNow(const char* path) noexcept {
  const int fd = ::open(path, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd >= 0) {
    alignas(8) char buffer[4096];
    // Entries removed while the folder is listed may shift the listing: list again until a
    // pass removes nothing.
    for (int pass = 0; pass < 64; ++pass) {
      bool removed = false;
      ::lseek(fd, 0, SEEK_SET);
      for (;;) {
        const long n = ::syscall(SYS_getdents64, fd, buffer, sizeof buffer);
        if (n <= 0) break;
        // struct linux_dirent64: d_ino (8 bytes), d_off (8), d_reclen (2), d_type (1), d_name.
        for (long offset = 0; offset < n;) {
          unsigned short length = 0;
          std::memcpy(&length, buffer + offset + 16, sizeof length);
          const char* name = buffer + offset + 19;
          offset += length;
          if (name[0] == '.' && (name[1] == '\0' || (name[1] == '.' && name[2] == '\0'))) continue;
          if (::unlinkat(fd, name, 0) == 0 || ::unlinkat(fd, name, AT_REMOVEDIR) == 0)
            removed = true;
        }
      }
      if (!removed) break;
    }
    ::close(fd);
  }
  ::rmdir(path);
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

namespace {

[[noreturn]] void failFolder(const fs::path& path, const std::string& reason) {
  throw IoError("cannot write the folder " + quoted(path) + ": " + reason);
}

std::string absoluteString(const fs::path& path) {
  std::error_code ignored;
  const fs::path absolute = fs::absolute(path, ignored);
  return absolute.empty() ? path.string() : absolute.string();
}

/// `text` with every `from` replaced by `to`.
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  if (from.empty()) return text;
  for (std::size_t at = text.find(from); at != std::string::npos;
       at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
  return text;
}

/// ".<name>." of `path`: the start of its temporaries' names. (Built by appending: GCC 12 warns
/// falsely, -Wrestrict, about "." + a string.)
std::string hiddenStem(const fs::path& path) {
  std::string stem(1, '.');
  stem += path.filename().string();
  stem += '.';
  return stem;
}

/// A new, empty temporary folder beside the target, listed for removeAtomicTemporaries()
/// before it exists, and removed with its content on destruction (after a swap it holds the
/// old folder).
class TemporaryFolder {
 public:
  TemporaryFolder(const fs::path& target, const fs::path& shown) {
    const fs::path directory = target.parent_path();
    const std::string stem = hiddenStem(target);
    for (int attempt = 0; attempt < 100; ++attempt) {
      path_ = directory / (stem + uniqueSuffix() + ".tmp");
      slot_ = listFolder(absoluteString(path_), "");
      if (::mkdir(path_.c_str(), 0777) == 0) return;
      const int error = errno;
      unlistFolder(slot_);
      slot_ = -1;
      if (error != EEXIST)
        failFolder(shown, "cannot create a temporary folder in " +
                              quoted(directory.empty() ? fs::path(".") : directory) + ": " +
                              std::strerror(error));
    }
    failFolder(shown, "no unique temporary folder name found");
  }
  TemporaryFolder(const TemporaryFolder&) = delete;
  TemporaryFolder& operator=(const TemporaryFolder&) = delete;
  ~TemporaryFolder() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
    unlistFolder(slot_);
  }

  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
  int slot_ = -1;
};

/// Whether `inner` is `outer` or lies inside it (both absolute and without symbolic links).
bool isWithin(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i)
    if (i == inner.end() || *i != *o) return false;
  return true;
}

}  // namespace

void writeFolderAtomically(const std::filesystem::path& requested,
                           const std::function<void(const std::filesystem::path&)>& fill) {
  fs::path given = requested;
  while (given.filename().empty() && given.has_relative_path())
    given = given.parent_path();  // "out/"
  const std::string name = given.filename().string();
  if (name.empty() || name == "." || name == "..")
    failFolder(requested, "not a folder name (give the folder's own name)");
  const fs::path shown = given.lexically_normal();

  std::error_code error;
  const fs::file_status status = fs::status(shown, error);  // through symbolic links
  const bool replacing = fs::exists(status);
  fs::path target = shown;
  struct stat old {};
  if (replacing) {
    if (!fs::is_directory(status)) failFolder(shown, "it exists and is not a folder");
    target = fs::canonical(shown, error);
    if (error) failFolder(shown, error.message());
    const fs::path cwd = fs::current_path(error);
    if (!error && isWithin(cwd, target))
      failFolder(shown, "it holds the current working folder, which cannot be replaced");
    if (::stat(target.c_str(), &old) != 0) failFolder(shown, std::strerror(errno));
  } else {
    if (fs::is_symlink(fs::symlink_status(shown, error)))
      failFolder(shown, "it is a symbolic link to nothing");
    if (const fs::path parent = shown.parent_path(); !parent.empty()) {
      fs::create_directories(parent, error);
      if (error) failFolder(shown, "cannot create its parent folder: " + error.message());
    }
  }

  TemporaryFolder temporary(target, shown);
  const fs::path& staging = temporary.path();
  if (replacing && ::chmod(staging.c_str(), old.st_mode & 07777) != 0)
    failFolder(shown, std::string("cannot give the new folder the old one's permissions: ") +
                          std::strerror(errno));
  try {
    fill(staging);
  } catch (const IoError& e) {
    // The files failed in the temporary folder; the user knows them by their final names.
    throw IoError(replaced(e.what(), staging.string(), shown.string()));
  }
  syncDirectory(staging);

  if (!replacing) {
    if (::rename(staging.c_str(), target.c_str()) != 0) failFolder(shown, std::strerror(errno));
  } else if (::renameat2(AT_FDCWD, staging.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE) !=
             0) {
    // A file system without the exchange: the old folder steps aside, the new one takes its
    // place. An interruption in between puts the old folder back (removeAtomicTemporaries).
    if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP)
      failFolder(shown, std::strerror(errno));
    const fs::path aside = target.parent_path() / (hiddenStem(target) + uniqueSuffix() + ".tmp");
    const int slot = listFolder(absoluteString(aside), absoluteString(target));
    if (::rename(target.c_str(), aside.c_str()) != 0) {
      const int reason = errno;
      unlistFolder(slot);
      failFolder(shown, std::strerror(reason));
    }
    if (::rename(staging.c_str(), target.c_str()) != 0) {
      const int reason = errno;
      ::rename(aside.c_str(), target.c_str());
      unlistFolder(slot);
      failFolder(shown, std::strerror(reason));
    }
    fs::remove_all(aside, error);
    unlistFolder(slot);
  }
  syncDirectory(target.parent_path());
  // `temporary` now removes the old folder (after the exchange it is at the temporary name).
}

void removeAtomicTemporaries() noexcept {
  // Files first: the temporaries of writes into a temporary folder are in it.
  for (Slot& slot : slots) {
    int expected = kListed;
    if (slot.state.compare_exchange_strong(expected, kRemoving, std::memory_order_acquire)) {
      ::unlink(slot.path);
      slot.state.store(kRemoved, std::memory_order_release);
    }
  }
  for (FolderSlot& slot : folderSlots) {
    int expected = kListed;
    if (slot.state.compare_exchange_strong(expected, kRemoving, std::memory_order_acquire)) {
      // An old folder between the two renames of a swap goes back where it was; once the new
      // folder is in its place, the rename fails and the old one is removed.
      if (slot.restore[0] == '\0' || ::rename(slot.path, slot.restore) != 0)
        removeFolderNow(slot.path);
      slot.state.store(kRemoved, std::memory_order_release);
    }
  }
}

}  // namespace spacewarp
