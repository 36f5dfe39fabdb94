#pragma once
// Writing a file so that readers only ever see the old content or the complete new one.

#include <filesystem>
#include <functional>
#include <ostream>

namespace spacewarp {

/// Writes a file atomically: `write` fills a temporary file with a unique name in the same
/// directory as `path` (opened in binary mode), which is then flushed, checked and renamed
/// over `path`, replacing any existing file there.
///
/// A failure never leaves a partial file or the temporary behind, and an existing file at
/// `path` is then left untouched:
/// - an I/O failure (the temporary cannot be created, the stream is in a failed state after
///   `write` returns, the rename fails) throws IoError naming `path`;
/// - any exception thrown by `write` is rethrown unchanged after the temporary is removed.
///
/// The new file gets the permissions of a newly created file (0666 minus the umask).
void writeFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write);

}  // namespace spacewarp
