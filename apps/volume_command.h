#pragma once
// `spacewarp deform` on OpenVDB files: every grid of the file warped by the rig's warp.

#include <filesystem>

#include <CLI/CLI.hpp>

#include "apps/cli_context.h"
#include "core/warp.h"

namespace spacewarp::cli {

/// The deform options that only volumes use.
struct VolumeCliOptions {};

/// Adds the volume options to `command`.
void addVolumeOptions(CLI::App* command, VolumeCliOptions& options);

/// True for paths the volume route handles (".vdb").
bool isVolumePath(const std::filesystem::path& path);

/// Warps every supported grid of `input` and writes them, with their names and metadata, to
/// `output` atomically.
void deformVolumeFile(const Warp& warp, const std::filesystem::path& input,
                      const std::filesystem::path& output, const VolumeCliOptions& options,
                      const CliContext& context);

}  // namespace spacewarp::cli
