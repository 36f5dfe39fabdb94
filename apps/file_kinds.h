#pragma once
// What kind of data a file holds, from its extension, so that `deform` can refuse an input
// and output that cannot be converted into each other before it does any work.

#include <filesystem>
#include <string>

namespace spacewarp::cli {

/// Geometry: polygon soups and point clouds (.obj, .off, .ply), converted freely between
/// formats. Volume: OpenVDB files (.vdb), written only as .vdb.
enum class FileKind { Geometry, Volume };

/// The extension of `path` in lower case, with its dot (".vdb"); "" if none.
std::string lowerExtension(const std::filesystem::path& path);

/// The kind of `path` from its extension, compared case-insensitively. Throws IoError naming
/// the file for a missing or unknown extension.
FileKind fileKind(const std::filesystem::path& path);

/// Throws CLI::ValidationError (a usage error, exit 2), in one line naming both files, unless
/// a file of the kind of `input` can be written as `output` (geometry to .obj, .off or .ply;
/// volume to .vdb). Both extensions must be known (see fileKind).
void checkConversion(const std::filesystem::path& input, const std::filesystem::path& output);

}  // namespace spacewarp::cli
