#include "apps/volume_command.h"

#include "core/errors.h"

namespace spacewarp::cli {

void addVolumeOptions(CLI::App*, VolumeCliOptions&) {}

bool isVolumePath(const std::filesystem::path& path) { return path.extension() == ".vdb"; }

void deformVolumeFile(const Warp&, const std::filesystem::path& input, const std::filesystem::path&,
                      const VolumeCliOptions&, const CliContext&) {
  throw InvalidInput(input.string() + ": volumes are not supported by this build");
}

}  // namespace spacewarp::cli
