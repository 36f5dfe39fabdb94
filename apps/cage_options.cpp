#include "apps/cage_options.h"

namespace spacewarp::cli {

// The help group of the harmonic method's options, also how checkCageMethodOptions finds them.
namespace {
const char* const kHarmonicGroup = "Options of --method harmonic";
}  // namespace

void addCageMethodOptions(CLI::App* command, CageMethodOptions& options) {
#ifdef SPACEWARP_HAVE_HARMONIC
  command
      ->add_option("--tets", options.harmonicTets,
                   "harmonic: target tet count of the cage's tetrahedralisation (default 200000)")
      ->check(CLI::PositiveNumber)
      ->group(kHarmonicGroup);
  command
      ->add_option("--harmonic-cache", options.harmonicCache,
                   "harmonic: solved-coordinate file, loaded if it matches the cage and --tets, "
                   "otherwise solved and written")
      ->group(kHarmonicGroup);
  command
      ->add_option("--outside", options.harmonicOutside,
                   "harmonic: points outside the cage raise an error or take the coordinates of "
                   "the nearest cage point")
      ->check(CLI::IsMember({"raise", "nearest"}))
      ->group(kHarmonicGroup);
#else
  (void)command;
  (void)options;
#endif
}

void checkCageMethodOptions(const CLI::App& command, const std::string& method) {
  if (method == "harmonic") return;
  for (const CLI::Option* option : command.get_options()) {
    if (option->get_group() != kHarmonicGroup || option->count() == 0) continue;
    throw CLI::ValidationError(
        option->get_name() + " applies to --method harmonic only" +
        (method.empty() ? " (with --rig, a harmonic rig's keys tets, cache and outside set it)"
                        : ", not to --method " + method));
  }
}

}  // namespace spacewarp::cli
