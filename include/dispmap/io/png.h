#pragma once
// PNG files for the images of core/height_image.h: greyscale heights read and written with
// libpng; also 8-bit RGBA PNG files (rendered frames, normal maps:
// writeRgbaPng, readRgbaPng). Needs libpng (and zlib).
//
// Reading accepts every PNG colour type whose pixels are grey:
//  * grey 1/2/4/8/16 bits: read as is (depths below 8 expanded to 8 bits);
//  * grey + alpha, and transparency (tRNS): alpha is dropped;
//  * palette and RGB(A): accepted when every pixel has R = G = B (grey saved as colour, as
//    many tools do), read exactly as that grey; a coloured pixel is a FileError naming it,
//    since no colour-to-height rule is right for every file (and libpng's rgb_to_gray would
//    also apply the file's gamma).
// Gamma chunks are ignored: the stored sample values are the heights. A 16-bit sample v
// becomes v / 65535, an 8-bit one v / 255. Writing always produces 16-bit greyscale.
//
// libpng reports errors by longjmp. The functions that call setjmp (detail::png*) hold no
// C++ objects; libpng's structs and all buffers are owned by their callers, so a longjmp
// never skips a destructor, and every libpng error becomes a FileError naming the file.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <png.h>

#include "dispmap/core/error.h"
#include "dispmap/core/height_image.h"
#include "dispmap/core/file_io.h" // detail::readFileBytes, detail::writeFileAtomically

namespace dispmap {

namespace detail {

// State shared with libpng's callbacks: the input bytes (reading) or output vector (writing)
// and the message of the error that made libpng longjmp.
struct PngIo {
    const unsigned char* in = nullptr;
    std::size_t inSize = 0, inPos = 0;
    std::vector<unsigned char>* out = nullptr;
    char message[256] = {};
};

// libpng error callback: keeps the message, then unwinds to the setjmp in detail::png*.
[[noreturn]] inline void pngOnError(png_structp png, png_const_charp message) {
    auto* io = static_cast<PngIo*>(png_get_error_ptr(png));
    std::snprintf(io->message, sizeof io->message, "%s", message);
    png_longjmp(png, 1);
}

// libpng warning callback: warnings (unknown chunks, bad ancillary CRCs) are not errors here.
inline void pngOnWarning(png_structp, png_const_charp) {}

// libpng read callback: copies the next bytes of the in-memory file, or fails as truncated.
inline void pngRead(png_structp png, png_bytep data, std::size_t length) {
    auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
    if (length > io->inSize - io->inPos) {
        char message[64];
        std::snprintf(message, sizeof message, "truncated at byte %zu", io->inSize);
        png_error(png, message);
    }
    std::memcpy(data, io->in + io->inPos, length);
    io->inPos += length;
}

// libpng write callback: appends to the output vector (out of memory becomes a libpng error).
inline void pngWrite(png_structp png, png_bytep data, std::size_t length) {
    auto* io = static_cast<PngIo*>(png_get_io_ptr(png));
    bool ok = true;
    try {
        io->out->insert(io->out->end(), data, data + length);
    } catch (...) {
        ok = false;
    }
    if (!ok) png_error(png, "out of memory");
}
inline void pngFlush(png_structp) {}

// Owns a libpng read or write struct and its info struct.
struct PngHandle {
    bool writing = false;
    png_structp png = nullptr;
    png_infop info = nullptr;
    PngHandle(const PngHandle&) = delete;
    PngHandle& operator=(const PngHandle&) = delete;
    PngHandle(bool forWriting, PngIo* io) : writing(forWriting) {
        png = writing ? png_create_write_struct(PNG_LIBPNG_VER_STRING, io, pngOnError, pngOnWarning)
                      : png_create_read_struct(PNG_LIBPNG_VER_STRING, io, pngOnError, pngOnWarning);
        if (png) info = png_create_info_struct(png);
    }
    ~PngHandle() {
        if (writing)
            png_destroy_write_struct(&png, info ? &info : nullptr);
        else
            png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
    }
};

// The decoded layout after libpng's transforms.
struct PngLayout {
    png_uint_32 width = 0, height = 0;
    int bitDepth = 0, channels = 0;
    std::size_t rowBytes = 0;
};

// Reads the PNG header and sets up the conversion to 8- or 16-bit grey or RGB without alpha.
// False (message in the PngIo) if libpng failed.
inline bool pngReadHeader(png_structp png, png_infop info, PngLayout* layout) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_read_info(png, info);
    if (png_get_color_type(png, info) == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (png_get_color_type(png, info) == PNG_COLOR_TYPE_GRAY && png_get_bit_depth(png, info) < 8)
        png_set_expand_gray_1_2_4_to_8(png);
    png_set_strip_alpha(png);
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    layout->width = png_get_image_width(png, info);
    layout->height = png_get_image_height(png, info);
    layout->bitDepth = png_get_bit_depth(png, info);
    layout->channels = png_get_channels(png, info);
    layout->rowBytes = png_get_rowbytes(png, info);
    return true;
}

// Decodes the image into rows and reads the rest of the file up to IEND. False on error.
inline bool pngReadRows(png_structp png, png_bytepp rows) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_read_image(png, rows);
    png_read_end(png, nullptr);
    return true;
}

// Encodes 16-bit grey rows (big-endian samples, as PNG stores them). False on error.
inline bool pngWriteGrey16(png_structp png, png_infop info, png_uint_32 width, png_uint_32 height,
                           png_bytepp rows) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_set_IHDR(png, info, width, height, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    png_write_image(png, rows);
    png_write_end(png, nullptr);
    return true;
}

// Reads the PNG header and sets up the conversion of any colour type to 8-bit RGBA (palette
// and grey expanded to RGB, tRNS to alpha, missing alpha filled with 255, 16-bit samples
// scaled to 8). False (message in the PngIo) if libpng failed.
inline bool pngReadHeaderRgba8(png_structp png, png_infop info, PngLayout* layout) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_read_info(png, info);
    const int colorType = png_get_color_type(png, info);
    if (colorType == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (colorType == PNG_COLOR_TYPE_GRAY && png_get_bit_depth(png, info) < 8) png_set_expand_gray_1_2_4_to_8(png);
    if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
    if (png_get_bit_depth(png, info) == 16) png_set_scale_16(png);
    if (colorType == PNG_COLOR_TYPE_GRAY || colorType == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_gray_to_rgb(png);
    png_set_add_alpha(png, 0xFF, PNG_FILLER_AFTER); // no effect where alpha exists
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    layout->width = png_get_image_width(png, info);
    layout->height = png_get_image_height(png, info);
    layout->bitDepth = png_get_bit_depth(png, info);
    layout->channels = png_get_channels(png, info);
    layout->rowBytes = png_get_rowbytes(png, info);
    return true;
}

// Encodes 8-bit RGBA rows. False on error.
inline bool pngWriteRgba8(png_structp png, png_infop info, png_uint_32 width, png_uint_32 height, png_bytepp rows) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB_ALPHA, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    png_write_image(png, rows);
    png_write_end(png, nullptr);
    return true;
}

// Big-endian u32 at bytes[at..at+3].
inline std::uint32_t bigEndian32(const std::vector<unsigned char>& bytes, std::size_t at) {
    return (std::uint32_t{bytes[at]} << 24) | (std::uint32_t{bytes[at + 1]} << 16) |
           (std::uint32_t{bytes[at + 2]} << 8) | std::uint32_t{bytes[at + 3]};
}

/// Largest PNG file read: the raw pixels of the largest image accepted (kMaxHeightImageSize^2
/// at 16-bit RGBA, 2 GiB) plus 1/16 for filter bytes and chunk framing. A PNG is never much
/// larger than its raw pixels: zlib stores incompressible data with 5 bytes per 64 KiB.
inline constexpr std::uint64_t kMaxPngFileBytes = (std::uint64_t{2} << 30) + (std::uint64_t{1} << 27);

/// What the IHDR chunk says, checked (checkPngHeader).
struct PngHeader {
    std::uint32_t width = 0, height = 0;
    int bitDepth = 0, colorType = 0, channels = 0;
    /// The bytes of the filtered image data (rows of 1 filter byte + samples, no interlacing):
    /// what the compressed IDAT data inflates to.
    std::uint64_t rawBytes = 0;
};

/// Throws fail(reason) unless `bytes` start with the PNG signature and an IHDR chunk of 13
/// bytes whose size is not zero and at most maxSide per side, whose bit depth and colour type
/// go together, and whose IDAT chunks hold at least rawBytes / 2048 bytes (deflate packs at
/// most ~1032 bytes into one: fewer is a truncated or forged file). All of this is read before
/// libpng allocates or decodes anything, so that an image above the caller's limit, or a
/// small file that claims a huge one, is refused at once and costs no memory.
template <class Fail> PngHeader checkPngHeader(const std::vector<unsigned char>& bytes, const Fail& fail, int maxSide) {
    const std::size_t sigBytes = std::min<std::size_t>(bytes.size(), 8);
    if (sigBytes == 0 || png_sig_cmp(bytes.data(), 0, sigBytes) != 0) throw fail("not a PNG file");
    constexpr std::size_t kHeaderEnd = 8 + 4 + 4 + 13 + 4; // signature, IHDR length, type, data, CRC
    if (bytes.size() < kHeaderEnd)
        throw fail("truncated at byte " + std::to_string(bytes.size()) + " (the signature and header take " +
                   std::to_string(kHeaderEnd) + ")");
    if (bigEndian32(bytes, 8) != 13 || std::memcmp(bytes.data() + 12, "IHDR", 4) != 0)
        throw fail("the first chunk is not a 13-byte IHDR header");
    PngHeader h;
    h.width = bigEndian32(bytes, 16);
    h.height = bigEndian32(bytes, 20);
    h.bitDepth = bytes[24];
    h.colorType = bytes[25];
    if (h.width == 0 || h.height == 0)
        throw fail("zero size (" + std::to_string(h.width) + " x " + std::to_string(h.height) + ")");
    const auto side = static_cast<std::uint32_t>(std::clamp(maxSide, 1, kMaxHeightImageSize));
    if (h.width > side || h.height > side)
        throw fail("too large (" + std::to_string(h.width) + " x " + std::to_string(h.height) + "; at most " +
                   std::to_string(side) + " per side)");
    const int d = h.bitDepth;
    switch (h.colorType) {
    case 0: h.channels = (d == 1 || d == 2 || d == 4 || d == 8 || d == 16) ? 1 : 0; break;  // grey
    case 2: h.channels = (d == 8 || d == 16) ? 3 : 0; break;                                  // RGB
    case 3: h.channels = (d == 1 || d == 2 || d == 4 || d == 8) ? 1 : 0; break;               // palette
    case 4: h.channels = (d == 8 || d == 16) ? 2 : 0; break;                                  // grey + alpha
    case 6: h.channels = (d == 8 || d == 16) ? 4 : 0; break;                                  // RGBA
    default: throw fail("unknown colour type " + std::to_string(h.colorType));
    }
    if (h.channels == 0)
        throw fail("bit depth " + std::to_string(d) + " is invalid for colour type " + std::to_string(h.colorType));
    const std::uint64_t rowBits = std::uint64_t{h.width} * static_cast<std::uint64_t>(h.channels * d);
    h.rawBytes = std::uint64_t{h.height} * (1 + (rowBits + 7) / 8);

    // The IDAT bytes present, summed over the chunks (framing checks, CRCs and the data itself
    // are libpng's; a chunk that runs past the end counts with the bytes that are there).
    std::uint64_t idat = 0;
    for (std::size_t at = kHeaderEnd; at + 8 <= bytes.size();) {
        const std::uint64_t length = bigEndian32(bytes, at);
        const bool isIdat = std::memcmp(bytes.data() + at + 4, "IDAT", 4) == 0;
        const std::uint64_t present = std::min<std::uint64_t>(length, bytes.size() - at - 8);
        if (isIdat) idat += present;
        if (std::memcmp(bytes.data() + at + 4, "IEND", 4) == 0 || present < length) break;
        at += static_cast<std::size_t>(8 + length + 4);
    }
    const std::uint64_t needed = h.rawBytes / 2048;
    if (idat < needed)
        throw fail("truncated or corrupt: " + std::to_string(idat) + " bytes of image data for " + std::to_string(h.width) +
                   " x " + std::to_string(h.height) + " pixels, which need at least " + std::to_string(needed));
    return h;
}

} // namespace detail

/// The width and height a PNG file's header states, from its first 24 bytes (nothing decoded;
/// readHeightPng and readRgbaPng check the rest). FileError naming the path for a file that
/// cannot be opened, is not a regular file, or does not start with a PNG signature and IHDR.
struct PngSize {
    int width = 0, height = 0;
};
inline PngSize readPngSize(const std::string& path, const char* what = "PNG image") {
    std::error_code ec;
    if (std::filesystem::status(path, ec).type() != std::filesystem::file_type::regular)
        detail::throwFileError("cannot open ", what, path, ec ? ec.message() : "not found or not a regular file");
    detail::FilePtr f(std::fopen(path.c_str(), "rb"));
    if (!f) detail::throwFileError("cannot open ", what, path, std::strerror(errno));
    std::vector<unsigned char> bytes(24);
    bytes.resize(std::fread(bytes.data(), 1, bytes.size(), f.get()));
    if (bytes.size() < 24 || png_sig_cmp(bytes.data(), 0, 8) != 0 || std::memcmp(bytes.data() + 12, "IHDR", 4) != 0)
        throw FileError(std::string(what) + " '" + path + "': not a PNG file (no signature and IHDR header)");
    return {static_cast<int>(std::min<std::uint32_t>(detail::bigEndian32(bytes, 16), 1u << 30)),
            static_cast<int>(std::min<std::uint32_t>(detail::bigEndian32(bytes, 20), 1u << 30))};
}

/// Reads a greyscale height image (see the top of this file for the accepted formats).
/// maxSide (at most kMaxHeightImageSize) is the caller's limit per side, checked from the
/// header before anything is decoded; `hint` is appended to that message (what to do instead).
/// Throws FileError naming path and the reason: cannot open, not a regular file, a file above
/// kMaxPngFileBytes, not a PNG, truncated, zero size, larger than maxSide per side, or any
/// error libpng reports.
inline HeightImage readHeightPng(const std::string& path, int maxSide = kMaxHeightImageSize,
                                 const std::string& hint = "") {
    const std::vector<unsigned char> bytes = detail::readFileBytes(path, "height image", detail::kMaxPngFileBytes);
    const auto fail = [&](const std::string& why) {
        return FileError("height image '" + path + "': " + why + (why.rfind("too large", 0) == 0 ? hint : ""));
    };

    detail::checkPngHeader(bytes, fail, maxSide);

    detail::PngIo io;
    io.in = bytes.data();
    io.inSize = bytes.size();
    detail::PngHandle handle(false, &io);
    if (!handle.png || !handle.info) throw fail("cannot initialise libpng");
    png_set_read_fn(handle.png, &io, detail::pngRead);
    png_set_user_limits(handle.png, kMaxHeightImageSize, kMaxHeightImageSize); // checked above; libpng's own guard too

    detail::PngLayout layout;
    if (!detail::pngReadHeader(handle.png, handle.info, &layout)) throw fail(io.message);
    const std::size_t channels = static_cast<std::size_t>(layout.channels);
    const std::size_t sampleBytes = static_cast<std::size_t>(layout.bitDepth / 8);
    if ((channels != 1 && channels != 3) || (layout.bitDepth != 8 && layout.bitDepth != 16) ||
        layout.rowBytes != std::size_t{layout.width} * channels * sampleBytes)
        throw fail("unsupported pixel layout after conversion (" + std::to_string(channels) + " channels, " +
                   std::to_string(layout.bitDepth) + " bits)");

    const std::size_t w = layout.width, h = layout.height;
    std::vector<unsigned char> pixels(layout.rowBytes * h);
    std::vector<png_bytep> rows(h);
    for (std::size_t y = 0; y < h; ++y)
        rows[y] = pixels.data() + y * layout.rowBytes;
    if (!detail::pngReadRows(handle.png, rows.data())) throw fail(io.message);

    HeightImage img;
    img.width = static_cast<int>(w);
    img.height = static_cast<int>(h);
    img.values.resize(w * h);
    const auto sample = [&](std::size_t i) { // sample i of the image, big-endian if 16-bit
        return sampleBytes == 2 ? (unsigned{pixels[2 * i]} << 8) | pixels[2 * i + 1] : unsigned{pixels[i]};
    };
    const float scale = sampleBytes == 2 ? 65535.0f : 255.0f;
    for (std::size_t i = 0; i < w * h; ++i) {
        const unsigned v = sample(channels * i);
        if (channels == 3 && (sample(3 * i + 1) != v || sample(3 * i + 2) != v))
            throw fail("pixel (" + std::to_string(i % w) + ", " + std::to_string(i / w) +
                       ") is coloured (R, G, B differ); a height image must be grey");
        img.values[i] = static_cast<float>(v) / scale;
    }
    return img;
}

/// Writes img as a 16-bit greyscale PNG (value v stored as round(v * 65535)), atomically:
/// a failed write leaves an existing file untouched and no temporary behind. Throws
/// ArgumentError (nothing written) unless 1 <= width, height <= kMaxHeightImageSize,
/// values.size() == width * height and every value is finite and in [0, 1] (the message
/// names the first bad texel); FileError if the file cannot be written.
inline void writeHeightPng16(const std::string& path, const HeightImage& img) {
    const auto invalid = [&](const std::string& why) {
        return ArgumentError("writeHeightPng16('" + path + "'): " + why);
    };
    if (img.width < 1 || img.height < 1 || img.width > kMaxHeightImageSize ||
        img.height > kMaxHeightImageSize)
        throw invalid("size " + std::to_string(img.width) + " x " + std::to_string(img.height) +
                      " is outside [1, " + std::to_string(kMaxHeightImageSize) + "] per side");
    const std::size_t w = static_cast<std::size_t>(img.width), h = static_cast<std::size_t>(img.height);
    if (img.values.size() != w * h)
        throw invalid(std::to_string(img.values.size()) + " values for a " + std::to_string(w) + " x " +
                      std::to_string(h) + " image");
    std::vector<unsigned char> pixels(2 * w * h);
    for (std::size_t i = 0; i < w * h; ++i) {
        const float v = img.values[i];
        if (!(v >= 0.0f && v <= 1.0f)) // also false for NaN
            throw invalid("texel (" + std::to_string(i % w) + ", " + std::to_string(i / w) + ") has value " +
                          std::to_string(v) + ", outside [0, 1]");
        const auto q = static_cast<std::uint16_t>(std::lround(static_cast<double>(v) * 65535.0));
        pixels[2 * i] = static_cast<unsigned char>(q >> 8);
        pixels[2 * i + 1] = static_cast<unsigned char>(q & 0xFF);
    }
    std::vector<png_bytep> rows(h);
    for (std::size_t y = 0; y < h; ++y)
        rows[y] = pixels.data() + 2 * w * y;

    std::vector<unsigned char> encoded;
    encoded.reserve(pixels.size() / 2 + 1024);
    detail::PngIo io;
    io.out = &encoded;
    detail::PngHandle handle(true, &io);
    if (!handle.png || !handle.info)
        throw FileError("cannot write height image '" + path + "': cannot initialise libpng");
    png_set_write_fn(handle.png, &io, detail::pngWrite, detail::pngFlush);
    if (!detail::pngWriteGrey16(handle.png, handle.info, static_cast<png_uint_32>(w),
                                static_cast<png_uint_32>(h), rows.data()))
        throw FileError("cannot write height image '" + path + "': " + io.message);
    detail::writeFileAtomically(path, encoded, "height image");
}

/// Writes width x height 8-bit RGBA pixels (row 0 at the top, 4 bytes per pixel) as a PNG,
/// atomically: a failed write leaves an existing file untouched and no temporary behind.
/// Throws ArgumentError (nothing written) unless 1 <= width, height <= kMaxHeightImageSize
/// and rgba is not null; FileError if the file cannot be written.
inline void writeRgbaPng(const std::string& path, int width, int height, const std::uint8_t* rgba) {
    if (width < 1 || height < 1 || width > kMaxHeightImageSize || height > kMaxHeightImageSize)
        throw ArgumentError("writeRgbaPng('" + path + "'): size " + std::to_string(width) + " x " +
                            std::to_string(height) + " is outside [1, " + std::to_string(kMaxHeightImageSize) +
                            "] per side");
    if (!rgba) throw ArgumentError("writeRgbaPng('" + path + "'): no pixels given");
    const std::size_t w = static_cast<std::size_t>(width), h = static_cast<std::size_t>(height);
    // libpng takes non-const row pointers but only reads them when writing.
    std::vector<std::uint8_t> pixels(rgba, rgba + 4 * w * h);
    std::vector<png_bytep> rows(h);
    for (std::size_t y = 0; y < h; ++y) rows[y] = pixels.data() + 4 * w * y;

    std::vector<unsigned char> encoded;
    encoded.reserve(pixels.size() / 2 + 1024);
    detail::PngIo io;
    io.out = &encoded;
    detail::PngHandle handle(true, &io);
    if (!handle.png || !handle.info) throw FileError("cannot write RGBA image '" + path + "': cannot initialise libpng");
    png_set_write_fn(handle.png, &io, detail::pngWrite, detail::pngFlush);
    if (!detail::pngWriteRgba8(handle.png, handle.info, static_cast<png_uint_32>(w), static_cast<png_uint_32>(h),
                               rows.data()))
        throw FileError("cannot write RGBA image '" + path + "': " + io.message);
    detail::writeFileAtomically(path, encoded, "RGBA image");
}

/// Reads a PNG as 8-bit RGBA: RGB, RGBA, grey (with or without alpha) and palette images of
/// any bit depth (grey becomes R = G = B, missing alpha 255, 16-bit samples are scaled to 8).
/// maxSide (at most kMaxHeightImageSize) is the caller's limit per side, checked from the
/// header before anything is decoded. Throws FileError naming path and the reason: cannot
/// open, not a regular file, a file above kMaxPngFileBytes, not a PNG, truncated, zero size,
/// larger than maxSide per side, or any error libpng reports.
inline RgbaImage readRgbaPng(const std::string& path, int maxSide = kMaxHeightImageSize) {
    const std::vector<unsigned char> bytes = detail::readFileBytes(path, "RGBA image", detail::kMaxPngFileBytes);
    const auto fail = [&](const std::string& why) { return FileError("RGBA image '" + path + "': " + why); };
    detail::checkPngHeader(bytes, fail, maxSide);
    detail::PngIo io;
    io.in = bytes.data();
    io.inSize = bytes.size();
    detail::PngHandle handle(false, &io);
    if (!handle.png || !handle.info) throw fail("cannot initialise libpng");
    png_set_read_fn(handle.png, &io, detail::pngRead);
    png_set_user_limits(handle.png, kMaxHeightImageSize, kMaxHeightImageSize);
    detail::PngLayout layout;
    if (!detail::pngReadHeaderRgba8(handle.png, handle.info, &layout)) throw fail(io.message);
    if (layout.channels != 4 || layout.bitDepth != 8 || layout.rowBytes != std::size_t{layout.width} * 4)
        throw fail("unsupported pixel layout after conversion (" + std::to_string(layout.channels) + " channels, " +
                   std::to_string(layout.bitDepth) + " bits)");
    RgbaImage img;
    img.width = static_cast<int>(layout.width);
    img.height = static_cast<int>(layout.height);
    img.rgba.resize(layout.rowBytes * layout.height);
    std::vector<png_bytep> rows(layout.height);
    for (std::size_t y = 0; y < layout.height; ++y) rows[y] = img.rgba.data() + y * layout.rowBytes;
    if (!detail::pngReadRows(handle.png, rows.data())) throw fail(io.message);
    return img;
}

} // namespace dispmap
