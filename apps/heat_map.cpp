#include "apps/heat_map.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include <stb_image_write.h>

#include "core/errors.h"
#include "core/io/atomic_file.h"

namespace spacewarp::cli {

namespace {

Rgb mix(Rgb a, Rgb b, double t) {
  auto channel = [t](std::uint8_t x, std::uint8_t y) {
    return static_cast<std::uint8_t>(std::lround(x + (y - x) * t));
  };
  return {channel(a.r, b.r), channel(a.g, b.g), channel(a.b, b.b)};
}

// Piecewise-linear through evenly spaced stops, t in [0, 1].
template <std::size_t N>
Rgb ramp(const std::array<Rgb, N>& stops, double t) {
  t = std::clamp(t, 0.0, 1.0) * (N - 1);
  const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(t), N - 2);
  return mix(stops[i], stops[i + 1], t - static_cast<double>(i));
}

// Viridis at five stops.
constexpr std::array<Rgb, 5> kPositive{
    {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}}};
// Pale pink to deep red: no hue in common with viridis.
constexpr std::array<Rgb, 3> kNegative{{{255, 196, 214}, {240, 80, 110}, {160, 0, 30}}};

}  // namespace

Rgb ColourScale::operator()(double value) const {
  if (value < 0.0) return ramp(kNegative, min < 0.0 ? value / min : 1.0);
  return ramp(kPositive, max > 0.0 ? value / max : 0.0);
}

void Image::line(double x0, double y0, double x1, double y1, Rgb colour) {
  // Steps of at most half a pixel along the longer axis: simple and gap-free.
  const double length = std::max(std::abs(x1 - x0), std::abs(y1 - y0));
  const int steps = std::max(1, static_cast<int>(std::ceil(2.0 * length)));
  for (int s = 0; s <= steps; ++s) {
    const double t = static_cast<double>(s) / steps;
    const long x = std::lround(x0 + (x1 - x0) * t), y = std::lround(y0 + (y1 - y0) * t);
    if (x >= 0 && y >= 0 && x < width && y < height)
      at(static_cast<int>(x), static_cast<int>(y)) = colour;
  }
}

void Image::paste(const Image& other, int x, int y) {
  for (int j = 0; j < other.height; ++j)
    for (int i = 0; i < other.width; ++i)
      if (x + i >= 0 && y + j >= 0 && x + i < width && y + j < height)
        at(x + i, y + j) = other.pixels[std::size_t(j) * other.width + i];
}

Image colourBar(const ColourScale& scale, int width, int height) {
  Image bar(width, height, Rgb{255, 255, 255});
  for (int i = 0; i < width; ++i) {
    const double v = scale.min + (scale.max - scale.min) * (i + 0.5) / width;
    for (int j = 0; j < height; ++j) bar.at(i, j) = scale(v);
  }
  if (scale.max > scale.min) {
    const double zero = -scale.min / (scale.max - scale.min) * width;
    bar.line(zero, 0, zero, height - 1, Rgb{0, 0, 0});
  }
  return bar;
}

void writePng(const Image& image, const std::filesystem::path& path) {
  std::string png;
  auto append = [](void* context, void* data, int size) {
    static_cast<std::string*>(context)->append(static_cast<const char*>(data),
                                               static_cast<std::size_t>(size));
  };
  if (!stbi_write_png_to_func(append, &png, image.width, image.height, 3, image.pixels.data(),
                              image.width * 3))
    throw IoError(path.string() + ": could not encode the PNG image");
  writeFileAtomically(path, [&](std::ostream& out) { out.write(png.data(), std::ssize(png)); });
}

}  // namespace spacewarp::cli
