#pragma once
// Writing a file so that readers only ever see the old content or the complete new one. Every
// file the project writes (meshes, point clouds, weights, images, reports, volumes, caches)
// goes through writeFileAtomically().

#include <filesystem>
#include <functional>
#include <ostream>

namespace spacewarp {

/// Writes a file atomically: `write` fills a temporary file with a unique name
/// (`.<name>.<16 hex digits>.tmp`) in the same directory as `path`, through a binary,
/// seekable stream; the temporary is then flushed, synced to disk (fsync), closed and renamed
/// over `path`, replacing any existing file there, and the directory is synced. A `path` that is
/// a symbolic link is written through: the file it points to is replaced, the link stays.
///
/// Every write is checked, as are the final flush, sync and close. A failure never leaves a
/// partial file or the temporary behind, and an existing file at `path` is then untouched:
/// - an I/O failure (the temporary cannot be created, a write fails — a full disk, a file
///   size limit —, `write` leaves the stream in a failed state, the sync, close or rename
///   fails) throws IoError naming `path` and the system's reason;
/// - any exception thrown by `write` is rethrown unchanged after the temporary is removed.
///
/// A file that is replaced keeps its permission bits; a new file gets those of a newly
/// created file (0666 minus the umask). While it exists, the temporary is listed for
/// removeAtomicTemporaries().
void writeFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write);

/// Removes (unlinks) the temporaries of every writeFileAtomically() in progress in this
/// process. Async-signal-safe: it is meant for a signal handler that then ends the process
/// (the spacewarp CLI's SIGINT/SIGTERM/SIGHUP handling), and does nothing else, so the
/// interrupted writes would fail if the process went on. At most 64 temporaries are listed at
/// once; further concurrent writes work but are not listed.
void removeAtomicTemporaries() noexcept;

}  // namespace spacewarp
