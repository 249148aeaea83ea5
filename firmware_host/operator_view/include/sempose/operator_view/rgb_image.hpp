// An 8-bit RGB picture to draw overlays on, and the PNG writer for it (libpng).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace sempose::operator_view {

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
};

struct RgbImage {
  int width = 0, height = 0;
  std::vector<Rgb> pixels;  // row-major

  RgbImage(int w, int h) : width(w), height(h), pixels(static_cast<std::size_t>(w) * h) {}
  // Pixel (x, y) if inside; drawing off the edge is clipped.
  void plot(int x, int y, Rgb c);
  void line(double x0, double y0, double x1, double y1, Rgb c);
  void circle(double cx, double cy, double r, Rgb c);
};

// Writes `img` as an 8-bit RGB PNG; throws std::runtime_error naming the file on failure.
void write_png(const std::string& path, const RgbImage& img);

}  // namespace sempose::operator_view
