#pragma once
// RGB images of scalar fields for `spacewarp compare`: a colour scale whose negative values
// stand out, line drawing for cage cross-sections, and atomic PNG output (stb).

#include <cstdint>
#include <filesystem>
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
};

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

/// A horizontal bar of the scale from min (left) to max (right), with a black tick at 0.
Image colourBar(const ColourScale& scale, int width, int height);

/// Writes `image` as PNG, atomically. Throws IoError naming the file on failure.
void writePng(const Image& image, const std::filesystem::path& path);

}  // namespace spacewarp::cli
