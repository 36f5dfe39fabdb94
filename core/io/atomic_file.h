#pragma once
// Writing a file so that readers only ever see the old content or the complete new one. Every
// file the project writes (meshes, point clouds, weights, images, reports, volumes, caches)
// goes through writeFileAtomically().

#include <filesystem>
#include <functional>
#include <ostream>
#include <string>

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

/// Writes a folder of files atomically, as a whole: `fill` writes the new content into a new,
/// empty temporary folder beside `path` (`.<name>.<16 hex digits>.tmp`, given to `fill`), which
/// then takes the place of `path`. Readers see either the complete old folder or the complete
/// new one, never a mix. An existing folder at `path` is replaced as a whole — anything else in
/// it is gone afterwards, so callers check that it holds only what they write — and is swapped
/// out in one step (Linux renameat2 RENAME_EXCHANGE; where the file system cannot, two renames
/// whose gap an interruption also recovers from). A `path` that is a symbolic link to a folder
/// is written through: the folder it names is replaced. Missing parent folders are created.
///
/// `fill` should write flat content (files, through writeFileAtomically, are best: their own
/// temporaries are listed too); the temporary folder is listed for removeAtomicTemporaries()
/// while it exists, which removes its files and empty subfolders.
///
/// If `fill` throws, or creating, syncing or swapping fails, the temporary folder is removed and
/// the old folder at `path` is untouched; an IoError that names the temporary folder is
/// rethrown naming `path` instead (a file that failed is named as it would have been), other
/// exceptions unchanged. Throws IoError naming `path` when it is not a folder, is the current
/// working folder or one of its parents, or the system refuses a step.
///
/// A replaced folder keeps its permission bits; a new one gets those of a newly created folder.
void writeFolderAtomically(const std::filesystem::path& path,
                           const std::function<void(const std::filesystem::path&)>& fill);

/// Removes the temporaries of every writeFileAtomically() (unlinks them) and
/// writeFolderAtomically() (removes their files and the folder; an old folder that was being
/// swapped out is put back if the new one is not in its place yet) in progress in this
/// process. Async-signal-safe: it is meant for a signal handler that then ends the process
/// (the spacewarp CLI's SIGINT/SIGTERM/SIGHUP handling), and does nothing else, so the
/// interrupted writes would fail if the process went on. At most 64 file and 8 folder
/// temporaries are listed at once; further concurrent writes work but are not listed.
void removeAtomicTemporaries() noexcept;

}  // namespace spacewarp
