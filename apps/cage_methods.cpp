#include "apps/cage_methods.h"

#include <functional>
#include <map>

#include "coords/green.h"
#include "coords/mean_value.h"
#include "core/coordinate_warp.h"
#include "core/errors.h"

namespace spacewarp::cli {

namespace {

using Factory = std::function<std::shared_ptr<const Coordinates>(
    std::shared_ptr<const Cage>, const CageMethodOptions&, const ProgressCallback&)>;

const std::map<std::string, Factory>& factories() {
  static const std::map<std::string, Factory> table = {
      {"mvc", [](auto cage, auto&, auto&) { return std::make_shared<MeanValueCoordinates>(cage); }},
      {"green", [](auto cage, auto&, auto&) { return std::make_shared<GreenCoordinates>(cage); }},
  };
  return table;
}

}  // namespace

void addCageMethodOptions(CLI::App*, CageMethodOptions&) {}

std::vector<std::string> cageMethods() {
  std::vector<std::string> names;
  for (const auto& [name, factory] : factories()) names.push_back(name);
  return names;
}

std::shared_ptr<const Coordinates> cageCoordinates(const std::string& method,
                                                   std::shared_ptr<const Cage> cage,
                                                   const CageMethodOptions& options,
                                                   const ProgressCallback& progress) {
  const auto it = factories().find(method);
  if (it == factories().end()) {
    std::string known;
    for (const std::string& m : cageMethods()) known += (known.empty() ? "" : ", ") + m;
    throw InvalidInput("unknown cage method '" + method + "' (one of: " + known + ")");
  }
  return it->second(std::move(cage), options, progress);
}

Rig cageRig(const std::string& method, const std::filesystem::path& cage,
            const std::filesystem::path& pose, const CageMethodOptions& options,
            const ProgressCallback& progress) {
  auto rest = std::make_shared<const Cage>(Cage::fromFile(cage));
  const std::vector<Vec3> posed = rest->posedVerticesFromFile(pose);
  auto coordinates = cageCoordinates(method, rest, options, progress);
  return {std::make_shared<CoordinateWarp>(coordinates, posed), coordinates};
}

}  // namespace spacewarp::cli
