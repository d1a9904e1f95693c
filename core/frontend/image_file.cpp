#include "core/frontend/image_file.h"

#include <fmt/core.h>
#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>

// jpeglib.h needs size_t and FILE declared first.
#include <jpeglib.h>

#include "core/common/error.h"

namespace marglab {
namespace {

// ---- PNG (libpng) ----
// libpng reports an error by longjmp to the last setjmp: the functions that call setjmp hold no
// object with a destructor, and every allocation happens between them, in ordinary C++ code.

struct PngContext {
  const uint8_t* data = nullptr;  // reading: the file's bytes
  size_t size = 0;
  size_t pos = 0;
  std::vector<uint8_t>* out = nullptr;  // writing
  char message[256] = "";
};

void pngError(png_structp png, png_const_charp message) {
  auto* c = static_cast<PngContext*>(png_get_error_ptr(png));
  std::snprintf(c->message, sizeof c->message, "%s", message);
  png_longjmp(png, 1);
}

void pngWarning(png_structp, png_const_charp) {}

void pngRead(png_structp png, png_bytep out, size_t n) {
  auto* c = static_cast<PngContext*>(png_get_io_ptr(png));
  if (n > c->size - c->pos) png_error(png, "the file ends early");
  std::memcpy(out, c->data + c->pos, n);
  c->pos += n;
}

void pngWrite(png_structp png, png_bytep in, size_t n) {
  auto* c = static_cast<PngContext*>(png_get_io_ptr(png));
  c->out->insert(c->out->end(), in, in + n);
}

void pngFlush(png_structp) {}

struct PngLayout {
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, channels = 0;
};

// The header and the transforms of imgcodecs' IMREAD_UNCHANGED: palettes to BGR(A), grey below 8
// bits to 8, transparency to alpha, 16-bit samples in the host's (little-endian) order.
bool pngReadLayout(png_structp png, png_infop info, PngLayout* layout) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_info(png, info);
  const int color_type = png_get_color_type(png, info);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (color_type == PNG_COLOR_TYPE_GRAY && png_get_bit_depth(png, info) < 8)
    png_set_expand_gray_1_2_4_to_8(png);
  if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
  if (png_get_bit_depth(png, info) == 16) png_set_swap(png);
  png_set_bgr(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  layout->width = png_get_image_width(png, info);
  layout->height = png_get_image_height(png, info);
  layout->bit_depth = png_get_bit_depth(png, info);
  layout->channels = png_get_channels(png, info);
  return true;
}

bool pngReadRows(png_structp png, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_image(png, rows);
  png_read_end(png, nullptr);
  return true;
}

cv::Mat decodePng(const std::vector<uint8_t>& bytes, const std::string& path) {
  PngContext context{bytes.data(), bytes.size()};
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &context, &pngError, &pngWarning);
  png_infop info = png != nullptr ? png_create_info_struct(png) : nullptr;
  if (info == nullptr) throw std::bad_alloc();
  struct Release {
    png_structp* png;
    png_infop* info;
    ~Release() { png_destroy_read_struct(png, info, nullptr); }
  } release{&png, &info};
  png_set_read_fn(png, &context, &pngRead);
  PngLayout layout;
  cv::Mat image;
  std::vector<png_bytep> rows;
  if (pngReadLayout(png, info, &layout)) {
    const int depth = layout.bit_depth == 16 ? CV_16U : CV_8U;
    image.create(static_cast<int>(layout.height), static_cast<int>(layout.width),
                 CV_MAKETYPE(depth, layout.channels));
    for (int r = 0; r < image.rows; ++r) rows.push_back(image.ptr(r));
    if (pngReadRows(png, rows.data())) return image;
  }
  throw InputError(path, 0, fmt::format("cannot decode the PNG image: {}", context.message));
}

bool pngWriteRows(png_structp png, png_infop info, const cv::Mat& image, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.cols),
               static_cast<png_uint_32>(image.rows), 8,
               image.channels() == 1 ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  png_set_bgr(png);
  png_write_image(png, rows);
  png_write_end(png, nullptr);
  return true;
}

// ---- JPEG (libjpeg) ----
// The same pattern: libjpeg's error_exit longjmps back into the function that called setjmp.

struct JpegError {
  jpeg_error_mgr manager;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX] = "";
};

void jpegErrorExit(j_common_ptr cinfo) {
  auto* error = reinterpret_cast<JpegError*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, error->message);
  std::longjmp(error->jump, 1);
}

// Grey stays grey, YCbCr / RGB becomes BGR (imgcodecs' IMREAD_UNCHANGED); false for other colour
// spaces (CMYK, YCCK) with the message set.
bool jpegStart(jpeg_decompress_struct* cinfo, JpegError* error, const std::vector<uint8_t>& bytes) {
  if (setjmp(error->jump)) return false;
  jpeg_mem_src(cinfo, bytes.data(), static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(cinfo, TRUE);
  if (cinfo->jpeg_color_space == JCS_GRAYSCALE) {
    cinfo->out_color_space = JCS_GRAYSCALE;
  } else if (cinfo->jpeg_color_space == JCS_YCbCr || cinfo->jpeg_color_space == JCS_RGB) {
    cinfo->out_color_space = JCS_EXT_BGR;
  } else {
    std::snprintf(error->message, sizeof error->message,
                  "colour space %d (expected grey or colour)",
                  static_cast<int>(cinfo->jpeg_color_space));
    return false;
  }
  jpeg_start_decompress(cinfo);
  return true;
}

bool jpegReadRows(jpeg_decompress_struct* cinfo, JpegError* error, cv::Mat* image) {
  if (setjmp(error->jump)) return false;
  while (cinfo->output_scanline < cinfo->output_height) {
    JSAMPROW row = image->ptr(static_cast<int>(cinfo->output_scanline));
    jpeg_read_scanlines(cinfo, &row, 1);
  }
  jpeg_finish_decompress(cinfo);
  return true;
}

cv::Mat decodeJpeg(const std::vector<uint8_t>& bytes, const std::string& path) {
  jpeg_decompress_struct cinfo;
  JpegError error;
  cinfo.err = jpeg_std_error(&error.manager);
  error.manager.error_exit = &jpegErrorExit;
  jpeg_create_decompress(&cinfo);
  struct Release {
    jpeg_decompress_struct* cinfo;
    ~Release() { jpeg_destroy_decompress(cinfo); }
  } release{&cinfo};
  cv::Mat image;
  if (jpegStart(&cinfo, &error, bytes)) {
    image.create(static_cast<int>(cinfo.output_height), static_cast<int>(cinfo.output_width),
                 CV_8UC(cinfo.output_components));
    if (jpegReadRows(&cinfo, &error, &image)) return image;
  }
  throw InputError(path, 0, fmt::format("cannot decode the JPEG image: {}", error.message));
}

std::vector<uint8_t> readBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "cannot open the image file");
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, 0, "cannot read the image file");
  return bytes;
}

}  // namespace

cv::Mat decodeImageFile(const std::string& path) {
  const std::vector<uint8_t> bytes = readBytes(path);
  if (bytes.size() >= 8 && png_sig_cmp(bytes.data(), 0, 8) == 0) return decodePng(bytes, path);
  if (bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) {
    return decodeJpeg(bytes, path);
  }
  throw InputError(path, 0, "cannot decode the image (expected a PNG or JPEG file)");
}

std::vector<uint8_t> encodePng(const cv::Mat& image) {
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3)) {
    throw std::invalid_argument("encodePng: expected an 8-bit grey or BGR image");
  }
  std::vector<uint8_t> out;
  PngContext context;
  context.out = &out;
  png_structp png =
      png_create_write_struct(PNG_LIBPNG_VER_STRING, &context, &pngError, &pngWarning);
  png_infop info = png != nullptr ? png_create_info_struct(png) : nullptr;
  if (info == nullptr) throw std::bad_alloc();
  struct Release {
    png_structp* png;
    png_infop* info;
    ~Release() { png_destroy_write_struct(png, info); }
  } release{&png, &info};
  png_set_write_fn(png, &context, &pngWrite, &pngFlush);
  std::vector<png_bytep> rows;
  for (int r = 0; r < image.rows; ++r) rows.push_back(const_cast<png_bytep>(image.ptr(r)));
  if (!pngWriteRows(png, info, image, rows.data())) {
    throw std::runtime_error(fmt::format("encodePng: {}", context.message));
  }
  return out;
}

}  // namespace marglab
