// Reading photos from files without trusting them: the size is
// taken from the header and refused above a pixel budget before anything is
// decoded, and a file is checked to be whole before OpenCV decodes it.
//
// Formats read: JPEG (the SOF segment), PNG (IHDR), TIFF and BigTIFF (the
// first IFD) and binary PGM/PPM (P5/P6). The format is told by the content,
// never by the name: a PNG named .jpg is read as the PNG it is (FormatNote
// says so for the log).
//
// ReadImageChecked() adds, before cv::imread:
//   JPEG  every segment walked by its length and the entropy-coded data
//         scanned up to the end-of-image marker FFD9 (anything after it is
//         padding and ignored); a file that ends before FFD9 is truncated:
//         what libjpeg reports only as the warning "Premature end of JPEG
//         file", which OpenCV ignores (it returns the image with the missing
//         rows gray).
//   PNG   every chunk's length and CRC-32, up to IEND.
//   PGM/PPM  the file holds the width x height samples its header declares.
// TIFF is decoded by libtiff through OpenCV; a broken strip makes imread
// fail, which is reported the same way.
//
// Every refusal throws IoError starting "image '<path>': " and giving the
// reason, e.g.
//   image 'a.jpg': truncated JPEG: the data ends at byte 16384 of 16384 before the end-of-image
//   marker FFD9 (libjpeg: "Premature end of JPEG file") image 'b.png': the PNG header claims 20000
//   x 20000 px (400.0 MP), more than max_megapixels 100; refused before decoding
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace slope_monitor {
namespace io {

struct ImageFileOptions {
  // Largest image accepted [megapixels, 1e6 px]: what the header claims is
  // refused above it before decoding (a 100 MP medium-format camera is the
  // largest a crew uses; decoded as 8-bit BGR that is 300 MB). > 0.
  double max_megapixels = 100.0;
  void Check() const;  // throws ConfigError naming the field
};

struct ImageHeader {
  int width = 0, height = 0;
  int channels = 0;    // samples per pixel in the file (a PNG palette counts as 3)
  int bit_depth = 8;   // bits per sample: 8 or 16 (JPEG: its precision, 8 or 12)
  std::string format;  // "jpeg", "png", "tiff", "pnm"
};

// Reads only the header. Throws IoError naming the path and what is wrong:
// missing, not a regular file, zero bytes, content not a format listed above
// (naming what it looks like: GIF, BMP, WebP, ...), a header without a size
// or with a zero size, or one that claims more than options.max_megapixels.
ImageHeader ReadImageHeader(const std::string& path, const ImageFileOptions& options = {});

// ReadImageHeader and the format's structure check above, without decoding
// (the file is read once, a buffer at a time): for checking a set of photos
// before any is used. Throws IoError as ReadImageHeader, and for a truncated
// or damaged file.
ImageHeader CheckImageFile(const std::string& path, const ImageFileOptions& options = {});

// CheckImageFile, then cv::imread(path, imread_flags). Throws IoError naming
// the path and the reason; never returns an empty Mat.
cv::Mat ReadImageChecked(const std::string& path, int imread_flags,
                         const ImageFileOptions& options = {});

// "" when the file's name ends as its format is usually named (.jpg/.jpeg,
// .png, .tif/.tiff, .pgm/.ppm/.pnm), else a note for the log:
// "image 'a.jpg': the content is PNG, not what the name says; read as PNG".
std::string FormatNote(const std::string& path, const ImageHeader& header);

}  // namespace io
}  // namespace slope_monitor
