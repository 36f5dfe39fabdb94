#pragma once
// RGB images of scalar fields for `spacewarp compare`: a colour scale whose negative values
// stand out, line drawing for cage cross-sections, text for titles and tick labels (stb's
// bitmap font), and atomic PNG output (stb).

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace spacewarp::cli {

struct Rgb {  // three bytes, so an Image is a packed RGB buffer
  std::uint8_t r = 0, g = 0, b = 0;
};

/// A row-major RGB image, row 0 at the top.
struct Image {
  int width = 0, height = 0;
  std::vector<Rgb> pixels;

  Image() = default;
  Image(int w, int h, Rgb fill) : width(w), height(h), pixels(std::size_t(w) * h, fill) {}
  Rgb& at(int x, int y) { return pixels[std::size_t(y) * width + x]; }

  /// Draws the segment (x0, y0)–(x1, y1) (pixel units, may be fractional or off the image),
  /// clipped to the image.
  void line(double x0, double y0, double x1, double y1, Rgb colour);

  /// Copies `other` with its top-left corner at (x, y), clipped.
  void paste(const Image& other, int x, int y);

  /// Draws one line of `text` (ASCII; other bytes draw as '?') in stb_easy_font's bitmap
  /// font, each font pixel a scale × scale block, with the text's top-left corner at (x, y),
  /// clipped to the image.
  void text(int x, int y, std::string_view text, int scale, Rgb colour);
};

/// Width and height in pixels of one line of `text` drawn at `scale` (descenders included).
int textWidth(std::string_view text, int scale);
int textHeight(int scale);

/// One colour scale shared by every image of a comparison: values in [min, max] with min ≤ 0
/// ≤ max. Non-negative values run through a viridis-like ramp (dark violet at 0, yellow at
/// max); negative values through a separate ramp from pale pink to deep red at min, so any
/// negative weight is visible at a glance.
struct ColourScale {
  double min = 0.0, max = 1.0;
  Rgb operator()(double value) const;
};

/// The colour for points where the field is not defined (outside the cage).
inline constexpr Rgb kOutside{236, 236, 236};

/// The fill of the panel of a method that failed: darker than kOutside, outside any ramp.
inline constexpr Rgb kFailed{128, 128, 128};

/// A horizontal bar of the scale from min (left) to max (right), with a black tick at 0.
Image colourBar(const ColourScale& scale, int width, int height);

/// The values a colour bar marks: min, max, and the multiples of a round step (1, 2 or 5
/// × 10^k, about `intervals` of them over the range) between them, 0 included; ascending.
std::vector<double> colourBarTicks(const ColourScale& scale, int intervals = 5);

/// A tick's label: the value to 3 significant digits ("-0.0813", "0.5", "1e-05").
std::string tickLabel(double value);

/// colourBar() of the scale with its numbers: min left of the bar and max right of it, then
/// under the bar a tick mark at each value of colourBarTicks() between them and its number
/// (0 first, then the others wherever a number does not touch one already placed). Text at
/// `textScale`; the bar is at least one line of text tall. An image too narrow for the numbers
/// beside the bar gets the bar across its whole width and no min/max numbers. Positions are
/// pixels from the image's top-left corner.
struct LabelledBar {
  Image image;                   ///< `width` wide
  std::vector<double> labelled;  ///< the values that got a number, ascending
  int barLeft = 0, barWidth = 0, barHeight = 0;
  int labelTop = 0;  ///< top of the numbers under the bar
};
LabelledBar labelledColourBar(const ColourScale& scale, int width, int barHeight, int textScale);

/// Writes `image` as PNG, atomically. Throws IoError naming the file on failure.
void writePng(const Image& image, const std::filesystem::path& path);

}  // namespace spacewarp::cli
