#include "apps/cage_options.h"

#include <algorithm>
#include <cstdlib>
#include <string>
#include <vector>

#ifdef SPACEWARP_HAVE_HARMONIC
#include <spacewarp/coords/harmonic.h>
#endif

namespace spacewarp::cli {

namespace {

const char* const kHarmonicGroup = "Options of --method harmonic";
const char* const kOutsideGroup = "Options of --method harmonic, wachspress, discrete-harmonic";

// The methods that read each option of addCageMethodOptions, by its name (edit regroups them).
struct OptionUse {
  const char* option;
  const char* rigKey;  // what sets it in a rig
  std::vector<std::string> methods;
};
const std::vector<OptionUse>& optionUses() {
  static const std::vector<OptionUse> uses = {
      {"--tets", "tets", {"harmonic"}},
      {"--precision", "precision", {"harmonic"}},
      {"--harmonic-cache", "cache", {"harmonic"}},
      {"--outside", "outside", {"harmonic", "wachspress", "discrete-harmonic"}},
  };
  return uses;
}

// "a, b or c"
std::string alternatives(const std::vector<std::string>& names) {
  std::string text;
  for (std::size_t k = 0; k < names.size(); ++k)
    text += (k == 0 ? "" : k + 1 == names.size() ? " or " : ", ") + names[k];
  return text;
}

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
#endif
  command
      ->add_option("--outside", options.outside,
                   "harmonic, wachspress, discrete-harmonic: points outside the cage raise an "
                   "error or take the coordinates of the nearest cage point")
      ->check(CLI::IsMember({"raise", "nearest"}))
      ->group(kOutsideGroup);
}

void checkCageMethodOptions(const CLI::App& command, const std::string& method,
                            const std::string& flag) {
  std::vector<std::string> methods;  // compare's --methods is a comma-separated list
  for (std::size_t begin = 0; begin <= method.size();) {
    const std::size_t end = std::min(method.find(',', begin), method.size());
    methods.push_back(method.substr(begin, end - begin));
    begin = end + 1;
  }
  for (const OptionUse& use : optionUses()) {
    const CLI::Option* option = command.get_option_no_throw(use.option);
    if (option == nullptr || option->count() == 0) continue;
    if (std::find_first_of(methods.begin(), methods.end(), use.methods.begin(),
                           use.methods.end()) != methods.end())
      continue;
    throw CLI::ValidationError(
        option->get_name() + " applies to --method " + alternatives(use.methods) + " only" +
        (method.empty() ? " (with --rig, the rig's key " + std::string(use.rigKey) + " sets it)"
                        : ", not to " + flag + " " + method));
  }
}

}  // namespace spacewarp::cli
