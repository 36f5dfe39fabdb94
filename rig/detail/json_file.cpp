#include <spacewarp/rig/detail/json_file.h>

#include <fstream>
#include <string_view>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/rig/rig.h>

namespace spacewarp::detail {

nlohmann::json readJsonFile(const std::filesystem::path& path, const std::string& noun,
                            const std::string& what) {
  const std::string where = printable(path.string());
  std::error_code error;
  if (std::filesystem::is_directory(path, error))
    throw IoError(where + ": is a directory, not a " + noun);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(where + ": cannot open the " + noun);
  // Read in blocks, so that binary or endless input (/dev/zero, a FIFO that never ends) is
  // refused at its first block or at the size limit instead of growing without bound.
  constexpr std::size_t kMaxBytes = std::size_t{1} << 30;
  std::string text;
  std::vector<char> block(std::size_t{1} << 16);
  while (in) {
    in.read(block.data(), static_cast<std::streamsize>(block.size()));
    const std::string_view got(block.data(), static_cast<std::size_t>(in.gcount()));
    if (const std::size_t nul = got.find('\0'); nul != std::string_view::npos) {
      throw IoError(where + ": not a " + noun + ": a NUL byte at byte offset " +
                    std::to_string(text.size() + nul) + " (" + what + " is JSON text)");
    }
    if (text.size() + got.size() > kMaxBytes)
      throw IoError(where + ": too large for a " + noun + " (over 1 GiB)");
    text.append(got);
  }
  if (in.bad()) throw IoError(where + ": cannot read the " + noun);
  return parseRigJson(text, where);
}

}  // namespace spacewarp::detail
