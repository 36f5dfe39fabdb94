#pragma once
// Reading a JSON file of the command line's (a rig, a handles file) with the same guards.

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace spacewarp::detail {

/// The JSON of `path`, read in blocks so that binary or endless input (/dev/zero, a FIFO) is
/// refused at its first block or at 1 GiB, then parsed by parseRigJson. IoError naming the file
/// and the `noun` ("rig file") for a folder, an unreadable file, a NUL byte ("`what` is JSON
/// text"); InvalidInput as parseRigJson.
nlohmann::json readJsonFile(const std::filesystem::path& path, const std::string& noun,
                            const std::string& what);

}  // namespace spacewarp::detail
