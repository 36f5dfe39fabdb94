#include "apps/cage_options.h"

#include <cstdlib>
#include <string>

#ifdef SPACEWARP_HAVE_HARMONIC
#include <spacewarp/coords/harmonic.h>
#endif

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
      ->add_option("--precision", options.harmonicPrecision,
                   "harmonic: precision level, a number in [1, 7]: a target of 200000 * 4^(p-5) "
                   "tets (5: the default resolution; 5.5 lies between 5 and 6); not with --tets")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            // Decimal only: strtod alone would take "0x5", "nan" and "inf", and CLI11's own
            // conversion reported "5x" as out of range.
            char* end = nullptr;
            const double value = std::strtod(text.c_str(), &end);
            const bool decimal = !text.empty() && end == text.c_str() + text.size() &&
                                 text.find_first_not_of("0123456789.eE+-") == std::string::npos;
            if (!decimal) return "--precision: '" + text + "' is not a number";
            if (!(value >= kHarmonicMinPrecision && value <= kHarmonicMaxPrecision))
              return "--precision: " + text + " is not in [1, 7]";
            return "";
          },
          "NUMBER in [1, 7]"))
      ->excludes("--tets")
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

void checkCageMethodOptions(const CLI::App& command, const std::string& method,
                            const std::string& flag) {
  if (method == "harmonic") return;
  for (const CLI::Option* option : command.get_options()) {
    if (option->get_group() != kHarmonicGroup || option->count() == 0) continue;
    throw CLI::ValidationError(
        option->get_name() + " applies to --method harmonic only" +
        (method.empty()
             ? " (with --rig, a harmonic rig's keys tets, precision, cache and outside set it)"
             : ", not to " + flag + " " + method));
  }
}

}  // namespace spacewarp::cli
