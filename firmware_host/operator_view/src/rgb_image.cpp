#include "sempose/operator_view/rgb_image.hpp"

#include <png.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "sempose/hal/cut_file.hpp"

namespace sempose::operator_view {

void RgbImage::plot(int x, int y, Rgb c) {
  if (x < 0 || y < 0 || x >= width || y >= height) return;
  pixels[static_cast<std::size_t>(y) * width + x] = c;
}

void RgbImage::line(double x0, double y0, double x1, double y1, Rgb c) {
  const double len = std::max(std::abs(x1 - x0), std::abs(y1 - y0));
  const int n = std::max(1, static_cast<int>(std::ceil(len)));
  for (int i = 0; i <= n; ++i) {
    const double t = static_cast<double>(i) / n;
    plot(static_cast<int>(std::lround(x0 + t * (x1 - x0))), static_cast<int>(std::lround(y0 + t * (y1 - y0))), c);
  }
}

void RgbImage::circle(double cx, double cy, double r, Rgb c) {
  const int n = std::max(16, static_cast<int>(2 * M_PI * r));
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    plot(static_cast<int>(std::lround(cx + r * std::cos(a))), static_cast<int>(std::lround(cy + r * std::sin(a))), c);
  }
}

void write_png(const std::string& path, const RgbImage& img) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) throw std::runtime_error(path + ": cannot write: " + std::strerror(errno));
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png != nullptr ? png_create_info_struct(png) : nullptr;
  if (png == nullptr || info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    std::fclose(f);
    throw std::runtime_error(path + ": libpng could not start");
  }
  // libpng reports errors by longjmp; nothing with a destructor lives between here and the end.
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    std::fclose(f);
    const bool removed = hal::remove_cut_file(path);  // a cut PNG would look like a picture to a file browser
    throw std::runtime_error(path + ": PNG write failed (disk full?); " + hal::cut_file_outcome(removed));
  }
  png_init_io(png, f);
  png_set_IHDR(png, info, static_cast<png_uint_32>(img.width), static_cast<png_uint_32>(img.height), 8, PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (int y = 0; y < img.height; ++y) {
    png_write_row(png, reinterpret_cast<png_const_bytep>(&img.pixels[static_cast<std::size_t>(y) * img.width]));
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  if (std::fclose(f) != 0) {
    const int err = errno;
    const bool removed = hal::remove_cut_file(path);
    throw std::runtime_error(path + ": cannot write: " + std::strerror(err) + "; " + hal::cut_file_outcome(removed));
  }
}

}  // namespace sempose::operator_view
