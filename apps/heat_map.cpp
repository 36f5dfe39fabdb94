#include "apps/heat_map.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include <stb_easy_font.h>
#include <stb_image_write.h>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>

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

// stb_easy_font's glyphs span rows 0-8 of a line (capitals from 0, descenders to 8); one
// more row keeps lines apart.
constexpr int kFontLineHeight = 10;

// The text as stb_easy_font takes it: a writable, NUL-terminated string of printable ASCII
// (its glyph table covers 32-126 and is indexed without a check).
std::string printable(std::string_view text) {
  std::string s(text);
  for (char& c : s)
    if (c < 32 || c > 126) c = '?';
  return s;
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

void Image::text(int x, int y, std::string_view text, int scale, Rgb colour) {
  std::string s = printable(text);
  // Each quad is 4 vertices of 16 bytes; stb_easy_font stops at the buffer's end, and no
  // glyph has more than 32 segments.
  std::vector<char> quads(64 * 32 * (s.size() + 1));
  const int count = stb_easy_font_print(0.0f, 0.0f, s.data(), nullptr, quads.data(),
                                        static_cast<int>(quads.size()));
  for (int q = 0; q < count; ++q) {
    // Vertex 0 is the quad's top-left corner and vertex 2 its bottom-right one, in whole
    // font pixels since the text starts at the origin.
    float corner[2][2];
    std::memcpy(corner[0], quads.data() + 64 * q, sizeof corner[0]);
    std::memcpy(corner[1], quads.data() + 64 * q + 32, sizeof corner[1]);
    const int x0 = x + scale * static_cast<int>(corner[0][0]);
    const int y0 = y + scale * static_cast<int>(corner[0][1]);
    const int x1 = x + scale * static_cast<int>(corner[1][0]);
    const int y1 = y + scale * static_cast<int>(corner[1][1]);
    for (int j = std::max(0, y0); j < std::min(height, y1); ++j)
      for (int i = std::max(0, x0); i < std::min(width, x1); ++i) at(i, j) = colour;
  }
}

int textWidth(std::string_view text, int scale) {
  std::string s = printable(text);
  // stb counts one spacing pixel after the last glyph: not part of the text's extent.
  return s.empty() ? 0 : scale * (stb_easy_font_width(s.data()) - 1);
}

int textHeight(int scale) { return scale * kFontLineHeight; }

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

std::vector<double> colourBarTicks(const ColourScale& scale, int intervals) {
  std::vector<double> ticks{scale.min};
  const double range = scale.max - scale.min;
  if (range > 0.0 && intervals > 0) {
    // step = unit × 10^exponent; a value k × step is computed as (k × unit) / 10^-exponent
    // when the exponent is negative, so 3 × 0.1 gives 0.3, not 0.30000000000000004.
    const double raw = range / intervals;
    const double exponent = std::floor(std::log10(raw));
    const double r = raw / std::pow(10.0, exponent);
    const double unit = r < 1.5 ? 1.0 : r < 3.5 ? 2.0 : r < 7.5 ? 5.0 : 10.0;
    auto value = [&](double k) {
      return exponent < 0.0 ? k * unit / std::pow(10.0, -exponent)
                            : k * unit * std::pow(10.0, exponent);
    };
    // Multiples strictly inside (min, max): the ends are ticks of their own.
    for (double k = std::floor(scale.min / value(1.0)) + 1.0; value(k) < scale.max; k += 1.0)
      if (value(k) > scale.min) ticks.push_back(value(k) == 0.0 ? 0.0 : value(k));
    ticks.push_back(scale.max);
  }
  return ticks;
}

std::string tickLabel(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", value == 0.0 ? 0.0 : value);  // no "-0"
  return text;
}

LabelledBar labelledColourBar(const ColourScale& scale, int width, int barHeight, int textScale) {
  const int tickLength = 2 + 2 * textScale, margin = 3 * textScale;
  const int lineHeight = textHeight(textScale);
  const std::string minLabel = tickLabel(scale.min), maxLabel = tickLabel(scale.max);
  LabelledBar result;
  result.barLeft = textWidth(minLabel, textScale) + margin;
  result.barWidth = width - result.barLeft - textWidth(maxLabel, textScale) - margin;
  // Too narrow for numbers beside the bar (a tiny image): the bar takes the whole width.
  const bool ends = result.barWidth >= width / 2;
  if (!ends) result.barLeft = 0, result.barWidth = width;
  result.barHeight = std::max(barHeight, lineHeight);
  result.labelTop = result.barHeight + tickLength;
  result.image = Image(width, result.labelTop + lineHeight, Rgb{255, 255, 255});
  Image& image = result.image;
  image.paste(colourBar(scale, result.barWidth, result.barHeight), result.barLeft, 0);

  // The ends beside the bar, so min, max and 0 never compete for the same place.
  const int textTop = (result.barHeight - lineHeight) / 2;
  if (ends) {
    image.text(0, textTop, minLabel, textScale, Rgb{0, 0, 0});
    image.text(result.barLeft + result.barWidth + margin, textTop, maxLabel, textScale,
               Rgb{0, 0, 0});
    result.labelled = {scale.min, scale.max};
  }

  // Tick marks under the bar, numbered by priority: 0, then the others left to right, each
  // where its number does not touch one already placed.
  std::vector<double> inner = colourBarTicks(scale);
  inner.erase(inner.begin());
  if (!inner.empty()) inner.pop_back();
  std::stable_partition(inner.begin(), inner.end(), [](double v) { return v == 0.0; });
  std::vector<std::pair<int, int>> taken;  // [left, right) of the numbers placed so far
  for (double v : inner) {
    const int x =
        result.barLeft + static_cast<int>(std::lround((v - scale.min) / (scale.max - scale.min) *
                                                      (result.barWidth - 1)));
    image.line(x, result.barHeight, x, result.labelTop - 1, Rgb{0, 0, 0});
    const std::string label = tickLabel(v);
    const int w = textWidth(label, textScale);
    const int left = std::clamp(x - w / 2, result.barLeft,
                                std::max(result.barLeft, result.barLeft + result.barWidth - w));
    if (std::any_of(taken.begin(), taken.end(), [&](const auto& t) {
          return left < t.second + margin && t.first < left + w + margin;
        }))
      continue;
    image.text(left, result.labelTop, label, textScale, Rgb{0, 0, 0});
    taken.emplace_back(left, left + w);
    result.labelled.push_back(v);
  }
  std::sort(result.labelled.begin(), result.labelled.end());
  return result;
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
