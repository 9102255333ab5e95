#pragma once
// Height images in the files sculpting and texturing tools export: OpenEXR (half, float and
// uint channels), TIFF (8/16/32-bit unsigned integer, 16/32/64-bit float samples) and PNG
// (io/png.h), one channel of one or several, single files and UDIM tile sets. Needs OpenEXR 3
// (with Imath) and libtiff 4.5, besides libpng.
//
// The format is told by the file's first bytes, not by its name: the PNG signature, the EXR
// magic number 76 2f 31 01, or a TIFF header ("II*\0", "MM\0*", BigTIFF "II+\0", "MM\0+").
//
// Values (HeightImage, row 0 the top row):
//  * integer samples are normalised to [0, 1]: a sample v of b bits becomes v / (2^b - 1);
//  * float samples (EXR half and float, TIFF IEEE float) are kept as they are, heights in scene
//    units (the caller applies its mid-level and scale); so are EXR's 32-bit uint samples
//    (converted to float, exact up to 2^24). A NaN or infinite sample is a FileError naming the
//    pixel and the channel.
//
// Channels (HeightReadOptions::channel):
//  * "" (the default): the only channel; where there are several, EXR takes "Y" (luminance)
//    if present, else "R"; TIFF takes sample 0 (the grey, or R of an RGB or palette image).
//  * EXR: a channel name, exactly as stored ("R", "Y", "height", "displacement.R").
//  * TIFF: a sample index ("0", "1", ...) or a name: "R", "G", "B" for RGB and palette images,
//    "Y" for the grey of a grey image, "A" for the first alpha sample.
//  * PNG: "", "0" or "Y" only: PNG heights are grey (io/png.h reads grey, and colour whose
//    pixels are all grey).
// A channel that is not in the file is a FileError naming the channels that are.
//
// OpenEXR: the first part of a multi-part file; level 0 of a tiled (mip- or rip-mapped) one.
// The image is the DATA window (its top-left pixel is row 0, column 0 whatever its origin); the
// display window is ignored. Deep images and subsampled channels are refused.
// TIFF: the first image (directory) of the file; strips or tiles, interleaved (contig) or
// separate planes, any compression this libtiff decodes; photometric min-is-black (grey), RGB
// and palette (the colour map's R, G or B, 16-bit, normalised by 65535). Refused with a
// FileError saying so: signed integer and complex samples, bit depths other than the above,
// min-is-white, CMYK, YCbCr, CIE Lab and the other photometric interpretations, more than 16
// samples per pixel, 3-D images, and every orientation but top-left (1, the default; the others
// are refused rather than flipped or transposed here, so that no map is ever read mirrored).
// 64-bit float samples are rounded to float (beyond float's range: a FileError).
//
// Safety: width and height are checked against HeightReadOptions::maxSide (overflow-safe)
// before any pixel is allocated. The EXR header is scanned here first (attribute sizes within
// the file, the data window, deep flags, the tile offset table within the file) before OpenEXR
// reads it, so that a small forged file cannot make OpenEXR allocate gigabytes; libtiff gets a
// per-handle limit on single allocations. Files are read whole (detail::readFileBytes) and
// decoded from memory: OpenEXR through an Imf::IStream over the bytes, libtiff through
// TIFFClientOpenExt with per-handle error handlers, whose first message goes into the
// FileError (warnings are dropped). No process-wide state of either library is changed.
// OpenEXR's exceptions (Iex, all derived from std::exception) become FileErrors naming the file.
//
// Writing (writeHeightExr, writeHeightTiff) encodes into memory, then writes the file
// atomically (detail::writeFileAtomically).
//
// Note: OpenEXR's headers declare a global type `half` (Imath's half.h); after this header, a
// local variable named `half` in code outside every namespace is a -Wshadow warning.
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <Imath/half.h>
#include <OpenEXR/IexBaseExc.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <tiffio.h>

#include "dispmap/core/error.h"
#include "dispmap/core/file_io.h" // detail::readFileBytes, detail::writeFileAtomically
#include "dispmap/core/height_image.h"
#include "dispmap/io/png.h"

namespace dispmap {

/// The formats readHeightImage reads.
enum class ImageFileFormat { Png, Exr, Tiff };

/// "PNG", "OpenEXR" or "TIFF".
inline const char* imageFileFormatName(ImageFileFormat format) {
    switch (format) {
    case ImageFileFormat::Png: return "PNG";
    case ImageFileFormat::Exr: return "OpenEXR";
    case ImageFileFormat::Tiff: return "TIFF";
    }
    return "?";
}

/// Largest EXR or TIFF file read: the raw pixels of the largest image accepted with 4 channels
/// of 32 bits (kMaxHeightImageSize^2 x 16 bytes, 4 GiB) plus 1/16 for headers, offset tables and
/// framing. PNG files have their own limit (detail::kMaxPngFileBytes).
inline constexpr std::uint64_t kMaxImageFileBytes = (std::uint64_t{4} << 30) + (std::uint64_t{1} << 28);

/// How readHeightImage reads a file.
struct HeightReadOptions {
    /// Largest width and height accepted (at most kMaxHeightImageSize): a larger image is a
    /// FileError before any pixel is allocated.
    int maxSide = kMaxHeightImageSize;
    /// Which channel holds the heights; "" picks one (see the top of this file).
    std::string channel;
};

/// What readHeightImage found in a file.
struct HeightImageInfo {
    ImageFileFormat format = ImageFileFormat::Png;
    /// Bits per sample of the channel read (EXR: 16 for half, 32 for float and uint).
    int bits = 0;
    /// The file stores floating-point samples (EXR half/float, TIFF IEEE float).
    bool floatSamples = false;
    /// Integer samples were normalised to [0, 1] (v / (2^bits - 1)); false for float samples
    /// and EXR uint samples, which are kept as they are.
    bool normalised = false;
    /// Channels in the file (TIFF: samples per pixel, 3 for a palette image's colour map).
    int channels = 0;
    /// The channel read: its name for EXR, its index ("0", "1", ...) for TIFF and PNG.
    std::string channel;
};

namespace detail {

/// The largest finite half (Imath's HALF_MAX, which is a double in some configurations).
inline constexpr float kHalfMax = 65504.0f;

// The format told by a file's first bytes, or false.
inline bool imageFormatOf(const unsigned char* b, std::size_t n, ImageFileFormat* format) {
    static const unsigned char png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
    if (n >= 8 && std::memcmp(b, png, 8) == 0) {
        *format = ImageFileFormat::Png;
        return true;
    }
    if (n >= 4 && b[0] == 0x76 && b[1] == 0x2f && b[2] == 0x31 && b[3] == 0x01) {
        *format = ImageFileFormat::Exr;
        return true;
    }
    if (n >= 4 && ((b[0] == 'I' && b[1] == 'I' && (b[2] == 42 || b[2] == 43) && b[3] == 0) ||
                   (b[0] == 'M' && b[1] == 'M' && b[2] == 0 && (b[3] == 42 || b[3] == 43)))) {
        *format = ImageFileFormat::Tiff;
        return true;
    }
    return false;
}

// Up to n first bytes of a regular file (0 if it is not one or cannot be opened: the caller
// then reads it with readFileBytes, which says why). Never opens a FIFO or device.
inline std::size_t readFileHead(const std::string& path, unsigned char* head, std::size_t n) {
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (ec || st.type() != std::filesystem::file_type::regular) return 0;
    FilePtr f(std::fopen(path.c_str(), "rb"));
    if (!f) return 0;
    return std::fread(head, 1, n, f.get());
}

// "(x, y) of channel 'c' is not finite (nan)" for the message of a non-finite sample.
inline std::string nonFiniteSample(std::size_t i, std::size_t width, const std::string& channel, double v) {
    return "pixel (" + std::to_string(i % width) + ", " + std::to_string(i / width) + ") of channel '" + channel +
           "' is not finite (" + (std::isnan(v) ? "nan" : v > 0 ? "+inf" : "-inf") + ")";
}

// 'a', 'b', 'c' (appended piecewise: GCC 12 at -O3 reports a false -Wrestrict for "'" + name).
inline std::string joinNames(const std::vector<std::string>& names) {
    std::string s;
    for (const std::string& n : names) {
        if (!s.empty()) s += ", ";
        s += '\'';
        s += excerpt(n);
        s += '\'';
    }
    return s;
}

// Throws ArgumentError (from `who`) unless img is a valid image of 1 to kMaxHeightImageSize
// pixels per side whose values are all finite.
inline void checkImageToWrite(const HeightImage& img, const std::string& who) {
    if (img.width < 1 || img.height < 1 || img.width > kMaxHeightImageSize || img.height > kMaxHeightImageSize)
        throw ArgumentError(who + ": size " + std::to_string(img.width) + " x " + std::to_string(img.height) +
                            " is outside [1, " + std::to_string(kMaxHeightImageSize) + "] per side");
    const std::size_t w = static_cast<std::size_t>(img.width), h = static_cast<std::size_t>(img.height);
    if (img.values.size() != w * h)
        throw ArgumentError(who + ": " + std::to_string(img.values.size()) + " values for a " + std::to_string(w) + " x " +
                            std::to_string(h) + " image");
    for (std::size_t i = 0; i < w * h; ++i)
        if (!std::isfinite(img.values[i]))
            throw ArgumentError(who + ": texel (" + std::to_string(i % w) + ", " + std::to_string(i / w) +
                                ") is not finite");
}

// ------------------------------------------------------------------------------------------
// OpenEXR

// An Imf::IStream over bytes in memory. A read past the end throws Iex::InputExc, as OpenEXR
// expects of a stream.
class ExrMemoryIStream final : public Imf::IStream {
  public:
    ExrMemoryIStream(const std::vector<unsigned char>& bytes, const std::string& name)
        : Imf::IStream(name.c_str()), bytes_(bytes) {}
    bool read(char c[], int n) override {
        if (n < 0 || pos_ > bytes_.size() || static_cast<std::uint64_t>(n) > bytes_.size() - pos_)
            throw Iex::InputExc("truncated: " + std::to_string(n) + " bytes asked at byte " + std::to_string(pos_) +
                                " of a " + std::to_string(bytes_.size()) + "-byte file");
        if (n > 0) std::memcpy(c, bytes_.data() + pos_, static_cast<std::size_t>(n));
        pos_ += static_cast<std::uint64_t>(n);
        return pos_ < bytes_.size();
    }
    std::uint64_t tellg() override { return pos_; }
    void seekg(std::uint64_t pos) override { pos_ = pos; }

  private:
    const std::vector<unsigned char>& bytes_;
    std::uint64_t pos_ = 0;
};

// An Imf::OStream appending to (and seeking within) a byte vector.
class ExrMemoryOStream final : public Imf::OStream {
  public:
    ExrMemoryOStream(std::vector<unsigned char>& out, const std::string& name) : Imf::OStream(name.c_str()), out_(out) {}
    void write(const char c[], int n) override {
        if (n < 0) throw Iex::ArgExc("negative write size");
        const std::uint64_t end = pos_ + static_cast<std::uint64_t>(n);
        if (end > out_.size()) out_.resize(static_cast<std::size_t>(end));
        if (n > 0) std::memcpy(out_.data() + pos_, c, static_cast<std::size_t>(n));
        pos_ = end;
    }
    std::uint64_t tellp() override { return pos_; }
    void seekp(std::uint64_t pos) override { pos_ = pos; }

  private:
    std::vector<unsigned char>& out_;
    std::uint64_t pos_ = 0;
};

inline std::uint32_t littleEndian32(const std::vector<unsigned char>& b, std::size_t at) {
    return std::uint32_t{b[at]} | (std::uint32_t{b[at + 1]} << 8) | (std::uint32_t{b[at + 2]} << 16) |
           (std::uint32_t{b[at + 3]} << 24);
}
inline std::int32_t littleEndianInt32(const std::vector<unsigned char>& b, std::size_t at) {
    const std::uint32_t u = littleEndian32(b, at);
    std::int32_t i;
    std::memcpy(&i, &u, sizeof i);
    return i;
}

// What the header scan found in one part of an EXR file.
struct ExrPartScan {
    bool hasWindow = false;
    std::int32_t xMin = 0, yMin = 0, xMax = 0, yMax = 0;
    bool hasTiles = false;
    std::uint32_t tileWidth = 0, tileHeight = 0;
    bool hasChunkCount = false;
    std::int32_t chunkCount = 0;
    std::string type; // "scanlineimage", "tiledimage", "deepscanline", "deeptile" or "" (single part)
};

// Width and height of the data window of part 0 of an EXR file, read from its header before
// OpenEXR sees it. Throws fail(reason) for a header that runs past the end or whose attribute
// sizes do not fit in the file (so OpenEXR never allocates for them), an unsupported version
// or flag, a deep image, a data window that is empty, inverted or larger than maxSide per side
// (computed in 64 bits: a forged window cannot overflow), and an offset table (tiles, or the
// chunk count of a multi-part file) that would not fit in the file.
template <class Fail>
std::pair<std::int64_t, std::int64_t> checkExrHeader(const std::vector<unsigned char>& b, const Fail& fail, int maxSide) {
    const auto truncated = [&](const std::string& where) {
        return fail("truncated or corrupt header (" + where + " runs past the end of the " + std::to_string(b.size()) +
                    "-byte file)");
    };
    if (b.size() < 8) throw truncated("the magic number and version");
    const std::uint32_t version = littleEndian32(b, 4);
    if ((version & 0xFFu) != 2) throw fail("unsupported OpenEXR version " + std::to_string(version & 0xFFu));
    constexpr std::uint32_t kTiled = 0x200, kLongNames = 0x400, kNonImage = 0x800, kMultiPart = 0x1000;
    if ((version & ~std::uint32_t{0xFF} & ~(kTiled | kLongNames | kNonImage | kMultiPart)) != 0)
        throw fail("unsupported OpenEXR flags (version field " + std::to_string(version) + ")");
    const bool multiPart = (version & kMultiPart) != 0;

    std::size_t at = 8;
    // A null-terminated name of at most 255 characters at `at`.
    const auto name = [&](const char* what) {
        const std::size_t end = std::min(b.size(), at + 256);
        for (std::size_t i = at; i < end; ++i)
            if (b[i] == 0) {
                std::string s(reinterpret_cast<const char*>(b.data() + at), i - at);
                at = i + 1;
                return s;
            }
        if (end == b.size()) throw truncated(what);
        throw fail(std::string("corrupt header (") + what + " longer than 255 characters)");
    };
    std::vector<ExrPartScan> parts;
    for (;;) {
        if (at >= b.size()) throw truncated("the header");
        if (multiPart && !parts.empty() && b[at] == 0) break; // the empty header ending the list
        ExrPartScan part;
        while (true) {
            if (at >= b.size()) throw truncated("the header");
            if (b[at] == 0) {
                ++at;
                break;
            }
            const std::string attr = name("an attribute name");
            const std::string type = name("an attribute type");
            if (b.size() - at < 4) throw truncated("attribute '" + excerpt(attr) + "'");
            const std::int32_t size = littleEndianInt32(b, at);
            at += 4;
            if (size < 0 || static_cast<std::uint64_t>(size) > b.size() - at)
                throw fail("truncated or corrupt header (attribute '" + excerpt(attr) + "' claims " + std::to_string(size) +
                           " bytes; " + std::to_string(b.size() - at) + " remain)");
            const std::size_t value = at;
            at += static_cast<std::size_t>(size);
            if (attr == "dataWindow" && type == "box2i" && size == 16) {
                part.hasWindow = true;
                part.xMin = littleEndianInt32(b, value);
                part.yMin = littleEndianInt32(b, value + 4);
                part.xMax = littleEndianInt32(b, value + 8);
                part.yMax = littleEndianInt32(b, value + 12);
            } else if (attr == "tiles" && type == "tiledesc" && size == 9) {
                part.hasTiles = true;
                part.tileWidth = littleEndian32(b, value);
                part.tileHeight = littleEndian32(b, value + 4);
            } else if (attr == "chunkCount" && type == "int" && size == 4) {
                part.hasChunkCount = true;
                part.chunkCount = littleEndianInt32(b, value);
            } else if (attr == "type" && type == "string") {
                part.type.assign(reinterpret_cast<const char*>(b.data() + value), static_cast<std::size_t>(size));
            }
        }
        parts.push_back(part);
        if (!multiPart) break;
    }

    const ExrPartScan& first = parts.front();
    if (first.type == "deepscanline" || first.type == "deeptile" || (!multiPart && (version & kNonImage) != 0))
        throw fail("a deep image (a varying number of samples per pixel); only flat images are read");
    if (!first.hasWindow) throw fail("corrupt header (no data window)");
    const std::int64_t width = std::int64_t{first.xMax} - first.xMin + 1;
    const std::int64_t height = std::int64_t{first.yMax} - first.yMin + 1;
    const std::string window = "data window (" + std::to_string(first.xMin) + ", " + std::to_string(first.yMin) +
                               ") - (" + std::to_string(first.xMax) + ", " + std::to_string(first.yMax) + ")";
    if (width < 1 || height < 1) throw fail("empty or inverted " + window);
    const std::int64_t side = std::clamp(maxSide, 1, kMaxHeightImageSize);
    if (width > side || height > side)
        throw fail("too large (" + std::to_string(width) + " x " + std::to_string(height) + ", " + window + "; at most " +
                   std::to_string(side) + " per side)");
    // Every chunk has an 8-byte entry in the offset table, which is in the file.
    const std::uint64_t maxChunks = b.size() / 8;
    if (!multiPart && ((version & kTiled) != 0 || first.hasTiles)) {
        if (!first.hasTiles || first.tileWidth == 0 || first.tileHeight == 0) throw fail("corrupt header (no tile size)");
        const std::uint64_t tiles = ((static_cast<std::uint64_t>(width) + first.tileWidth - 1) / first.tileWidth) *
                                    ((static_cast<std::uint64_t>(height) + first.tileHeight - 1) / first.tileHeight);
        if (tiles > maxChunks)
            throw fail("truncated or corrupt: " + std::to_string(tiles) + " tiles of " + std::to_string(first.tileWidth) +
                       " x " + std::to_string(first.tileHeight) + " need a larger offset table than the file holds");
    }
    if (multiPart)
        for (std::size_t p = 0; p < parts.size(); ++p)
            if (!parts[p].hasChunkCount || parts[p].chunkCount < 0 ||
                static_cast<std::uint64_t>(parts[p].chunkCount) > maxChunks)
                throw fail("truncated or corrupt: part " + std::to_string(p) + " has no valid chunk count for a file of " +
                           std::to_string(b.size()) + " bytes");
    return {width, height};
}

// Reads one channel of the first part of an EXR file in memory (see the top of this file).
template <class Fail>
HeightImage readHeightExr(const std::vector<unsigned char>& bytes, const std::string& path, const Fail& fail,
                          const HeightReadOptions& options, HeightImageInfo* info) {
    const auto size = checkExrHeader(bytes, fail, options.maxSide);
    try {
        ExrMemoryIStream stream(bytes, path);
        Imf::InputFile file(stream);
        const Imf::Header& header = file.header();
        const Imath::Box2i window = header.dataWindow();
        const std::int64_t width = std::int64_t{window.max.x} - window.min.x + 1;
        const std::int64_t height = std::int64_t{window.max.y} - window.min.y + 1;
        if (width != size.first || height != size.second) throw fail("corrupt header (data window changed)");

        const Imf::ChannelList& channels = header.channels();
        std::vector<std::string> names;
        for (Imf::ChannelList::ConstIterator c = channels.begin(); c != channels.end(); ++c) names.emplace_back(c.name());
        if (names.empty()) throw fail("has no channels");
        const auto has = [&](const std::string& n) { return std::find(names.begin(), names.end(), n) != names.end(); };
        std::string name = options.channel;
        if (name.empty()) {
            if (names.size() == 1)
                name = names.front();
            else if (has("Y"))
                name = "Y";
            else if (has("R"))
                name = "R";
            else
                throw fail("has channels " + joinNames(names) + " and none is 'Y' or 'R': choose one");
        } else if (!has(name)) {
            throw fail("has no channel '" + excerpt(name) + "' (its channels: " + joinNames(names) + ")");
        }
        const Imf::Channel& channel = *channels.findChannel(name);
        if (channel.xSampling != 1 || channel.ySampling != 1)
            throw fail("channel '" + excerpt(name) + "' is subsampled (" + std::to_string(channel.xSampling) + " x " +
                       std::to_string(channel.ySampling) + "); only full-resolution channels are read");
        if (!file.isComplete()) throw fail("truncated or incomplete (pixel blocks are missing)");

        const std::size_t w = static_cast<std::size_t>(width), h = static_cast<std::size_t>(height);
        HeightImage img;
        img.width = static_cast<int>(w);
        img.height = static_cast<int>(h);
        img.values.assign(w * h, 0.0f);
        Imf::FrameBuffer frame;
        frame.insert(name, Imf::Slice::Make(Imf::FLOAT, img.values.data(), window));
        file.setFrameBuffer(frame);
        file.readPixels(window.min.y, window.max.y);
        for (std::size_t i = 0; i < w * h; ++i)
            if (!std::isfinite(img.values[i]))
                throw fail(nonFiniteSample(i, w, name, static_cast<double>(img.values[i])));
        if (info) {
            info->format = ImageFileFormat::Exr;
            info->bits = channel.type == Imf::HALF ? 16 : 32;
            info->floatSamples = channel.type != Imf::UINT;
            info->normalised = false;
            info->channels = static_cast<int>(names.size());
            info->channel = name;
        }
        return img;
    } catch (const FileError&) {
        throw;
    } catch (const std::exception& e) {
        throw fail(std::string("OpenEXR: ") + e.what());
    }
}

// ------------------------------------------------------------------------------------------
// libtiff

// State shared with libtiff's callbacks: the input bytes (reading) or the output vector
// (writing), the position, and the first error libtiff reported for this handle.
struct TiffIo {
    const unsigned char* in = nullptr;
    std::size_t inSize = 0;
    std::vector<unsigned char>* out = nullptr;
    std::uint64_t pos = 0;
    const char* name = ""; // the name given to libtiff, left out of its messages
    char message[512] = {};
};

inline tmsize_t tiffRead(thandle_t handle, void* buf, tmsize_t n) {
    auto* io = static_cast<TiffIo*>(handle);
    const unsigned char* data = io->out ? io->out->data() : io->in;
    const std::uint64_t size = io->out ? io->out->size() : io->inSize;
    if (n < 0) return -1;
    if (io->pos >= size) return 0;
    const std::uint64_t k = std::min<std::uint64_t>(static_cast<std::uint64_t>(n), size - io->pos);
    if (k > 0) std::memcpy(buf, data + io->pos, static_cast<std::size_t>(k));
    io->pos += k;
    return static_cast<tmsize_t>(k);
}

inline tmsize_t tiffWrite(thandle_t handle, void* buf, tmsize_t n) {
    auto* io = static_cast<TiffIo*>(handle);
    if (!io->out || n < 0) return -1;
    const std::uint64_t end = io->pos + static_cast<std::uint64_t>(n);
    if (end > io->out->size()) {
        bool ok = true;
        try {
            io->out->resize(static_cast<std::size_t>(end));
        } catch (...) {
            ok = false;
        }
        if (!ok) return -1;
    }
    if (n > 0) std::memcpy(io->out->data() + io->pos, buf, static_cast<std::size_t>(n));
    io->pos = end;
    return n;
}

inline toff_t tiffSeek(thandle_t handle, toff_t offset, int whence) {
    auto* io = static_cast<TiffIo*>(handle);
    const std::uint64_t size = io->out ? io->out->size() : io->inSize;
    const std::uint64_t base = whence == SEEK_CUR ? io->pos : whence == SEEK_END ? size : 0;
    // offset is signed for SEEK_CUR and SEEK_END (libtiff casts it): wrap-around arithmetic.
    const std::uint64_t to = base + offset;
    if (to > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) return static_cast<toff_t>(-1);
    io->pos = to;
    return to;
}

inline int tiffClose(thandle_t) { return 0; }
inline toff_t tiffSize(thandle_t handle) {
    auto* io = static_cast<TiffIo*>(handle);
    return io->out ? io->out->size() : io->inSize;
}
inline int tiffMap(thandle_t, void**, toff_t*) { return 0; }
inline void tiffUnmap(thandle_t, void*, toff_t) {}

// Per-handle error handler: keeps the first message (later ones usually follow from it).
inline int tiffOnError(TIFF*, void* user, const char* module, const char* fmt, va_list args) {
    auto* io = static_cast<TiffIo*>(user);
    if (io->message[0] != '\0') return 1;
    int k = 0;
    if (module && *module && std::strcmp(module, io->name) != 0)
        k = std::max(0, std::snprintf(io->message, sizeof io->message, "%s: ", module));
    if (static_cast<std::size_t>(k) < sizeof io->message)
        std::vsnprintf(io->message + k, sizeof io->message - static_cast<std::size_t>(k), fmt, args);
    return 1; // handled: not passed on to libtiff's global handlers
}
// Per-handle warning handler: warnings (unknown tags, odd but readable files) are not errors.
inline int tiffOnWarning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

struct TiffCloser {
    void operator()(TIFF* tif) const { TIFFClose(tif); }
};
using TiffPtr = std::unique_ptr<TIFF, TiffCloser>;
struct TiffOptionsFree {
    void operator()(TIFFOpenOptions* opts) const { TIFFOpenOptionsFree(opts); }
};

// Opens a TIFF over io (mode "rm": read, no memory mapping; "w": write), with io's error and
// warning handlers and a limit on libtiff's single allocations. Null on failure (io.message).
inline TiffPtr tiffOpen(TiffIo& io, const char* mode, tmsize_t maxSingleAlloc) {
    const std::unique_ptr<TIFFOpenOptions, TiffOptionsFree> opts(TIFFOpenOptionsAlloc());
    if (!opts) return nullptr;
    TIFFOpenOptionsSetErrorHandlerExtR(opts.get(), tiffOnError, &io);
    TIFFOpenOptionsSetWarningHandlerExtR(opts.get(), tiffOnWarning, &io);
    TIFFOpenOptionsSetMaxSingleMemAlloc(opts.get(), maxSingleAlloc);
    return TiffPtr(TIFFClientOpenExt(io.name, mode, &io, tiffRead, tiffWrite, tiffSeek, tiffClose, tiffSize, tiffMap,
                                     tiffUnmap, opts.get()));
}

inline std::string tiffPhotometricName(unsigned photometric) {
    switch (photometric) {
    case PHOTOMETRIC_MINISWHITE: return "min-is-white";
    case PHOTOMETRIC_MINISBLACK: return "min-is-black";
    case PHOTOMETRIC_RGB: return "RGB";
    case PHOTOMETRIC_PALETTE: return "palette";
    case PHOTOMETRIC_MASK: return "transparency mask";
    case PHOTOMETRIC_SEPARATED: return "separated (CMYK)";
    case PHOTOMETRIC_YCBCR: return "YCbCr";
    case PHOTOMETRIC_CIELAB: return "CIE L*a*b*";
    case PHOTOMETRIC_ICCLAB: return "ICC L*a*b*";
    case PHOTOMETRIC_ITULAB: return "ITU L*a*b*";
    case PHOTOMETRIC_CFA: return "colour filter array";
    case PHOTOMETRIC_LOGL: return "LogL";
    case PHOTOMETRIC_LOGLUV: return "LogLuv";
    default: return "unknown";
    }
}

// Reads one channel of the first image of a TIFF file in memory (see the top of this file).
template <class Fail>
HeightImage readHeightTiff(const std::vector<unsigned char>& bytes, const std::string& path, const Fail& fail,
                           const HeightReadOptions& options, HeightImageInfo* info) {
    TiffIo io;
    io.in = bytes.data();
    io.inSize = bytes.size();
    io.name = path.c_str();
    const auto libtiffError = [&](const std::string& what) {
        return fail(what + (io.message[0] ? std::string(": ") + io.message : std::string()));
    };
    // libtiff's own buffers (raw strips, tag arrays) hold what is in the file; the pixels are ours.
    const std::uint64_t allocLimit = 2 * std::uint64_t{bytes.size()} + (std::uint64_t{64} << 20);
    const TiffPtr tif = tiffOpen(io, "rm", static_cast<tmsize_t>(allocLimit));
    if (!tif) throw libtiffError("libtiff cannot read it");
    TIFF* t = tif.get();

    std::uint32_t width = 0, height = 0, depth = 1;
    if (TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &width) != 1 || TIFFGetField(t, TIFFTAG_IMAGELENGTH, &height) != 1)
        throw fail("no image width or length tag");
    if (width == 0 || height == 0)
        throw fail("zero size (" + std::to_string(width) + " x " + std::to_string(height) + ")");
    const auto side = static_cast<std::uint32_t>(std::clamp(options.maxSide, 1, kMaxHeightImageSize));
    if (width > side || height > side)
        throw fail("too large (" + std::to_string(width) + " x " + std::to_string(height) + "; at most " +
                   std::to_string(side) + " per side)");
    TIFFGetField(t, TIFFTAG_IMAGEDEPTH, &depth);
    if (depth != 1) throw fail("a 3-D image (depth " + std::to_string(depth) + ") is not supported");

    std::uint16_t spp = 1, bits = 1, format = SAMPLEFORMAT_UINT, photometric = 0, planar = PLANARCONFIG_CONTIG;
    std::uint16_t orientation = ORIENTATION_TOPLEFT;
    TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &spp);
    TIFFGetFieldDefaulted(t, TIFFTAG_BITSPERSAMPLE, &bits);
    TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLEFORMAT, &format);
    TIFFGetFieldDefaulted(t, TIFFTAG_PLANARCONFIG, &planar);
    TIFFGetFieldDefaulted(t, TIFFTAG_ORIENTATION, &orientation);
    if (TIFFGetField(t, TIFFTAG_PHOTOMETRIC, &photometric) != 1) throw fail("no photometric interpretation tag");
    if (spp < 1 || spp > 16)
        throw fail(std::to_string(spp) + " samples per pixel are not supported (1 to 16)");
    const bool floating = format == SAMPLEFORMAT_IEEEFP;
    if (format == SAMPLEFORMAT_INT)
        throw fail("signed integer samples are not supported (save unsigned integer or float samples)");
    if (!floating && format != SAMPLEFORMAT_UINT && format != SAMPLEFORMAT_VOID)
        throw fail("sample format " + std::to_string(format) + " (complex) is not supported");
    if (floating ? (bits != 16 && bits != 32 && bits != 64) : (bits != 8 && bits != 16 && bits != 32))
        throw fail(std::to_string(bits) + "-bit " + (floating ? "float" : "integer") +
                   " samples are not supported (8, 16 or 32 bits for integers; 16, 32 or 64 for floats)");
    if (orientation != ORIENTATION_TOPLEFT)
        throw fail("orientation " + std::to_string(orientation) +
                   " is not supported: only top-left (1, row 0 at the top, column 0 at the left)");
    if (planar != PLANARCONFIG_CONTIG && planar != PLANARCONFIG_SEPARATE)
        throw fail("planar configuration " + std::to_string(planar) + " is not supported");

    // The channels and their names; palette images have the colour map's R, G, B.
    const bool palette = photometric == PHOTOMETRIC_PALETTE;
    const bool rgb = photometric == PHOTOMETRIC_RGB;
    if (photometric != PHOTOMETRIC_MINISBLACK && !rgb && !palette)
        throw fail("photometric interpretation " + std::to_string(photometric) + " (" + tiffPhotometricName(photometric) +
                   ") is not supported: grey (min-is-black), RGB or palette");
    if (rgb && spp < 3) throw fail("an RGB image with " + std::to_string(spp) + " samples per pixel");
    if (palette && (spp != 1 || floating || (bits != 8 && bits != 16)))
        throw fail("a palette image must have one 8- or 16-bit integer sample per pixel");
    const int channelCount = palette ? 3 : spp;
    std::vector<std::string> names(static_cast<std::size_t>(channelCount));
    int alpha = -1;
    {
        std::uint16_t extraCount = 0;
        std::uint16_t* extra = nullptr;
        TIFFGetFieldDefaulted(t, TIFFTAG_EXTRASAMPLES, &extraCount, &extra);
        const int colour = palette ? 3 : rgb ? 3 : 1;
        for (int c = 0; c < channelCount; ++c) {
            std::string n = std::to_string(c);
            if (c < colour) {
                n += rgb || palette ? (c == 0 ? " (R)" : c == 1 ? " (G)" : " (B)") : " (grey)";
            } else if (extra && c - colour < extraCount &&
                       (extra[c - colour] == EXTRASAMPLE_ASSOCALPHA || extra[c - colour] == EXTRASAMPLE_UNASSALPHA) &&
                       alpha < 0) {
                alpha = c;
                n += " (A)";
            }
            names[static_cast<std::size_t>(c)] = n;
        }
    }
    int channel = -1;
    const std::string& asked = options.channel;
    if (asked.empty()) {
        channel = 0;
    } else if (asked.size() <= 2 && std::all_of(asked.begin(), asked.end(), [](char c) { return c >= '0' && c <= '9'; })) {
        channel = std::stoi(asked);
    } else if ((rgb || palette) && (asked == "R" || asked == "G" || asked == "B")) {
        channel = asked == "R" ? 0 : asked == "G" ? 1 : 2;
    } else if (!rgb && !palette && asked == "Y") {
        channel = 0;
    } else if (asked == "A") {
        channel = alpha;
    }
    if (channel < 0 || channel >= channelCount)
        throw fail("has no channel '" + excerpt(asked) + "' (its channels: " + joinNames(names) + ")");
    const int sample = palette ? 0 : channel;

    // The colour map of a palette image: the chosen component of each of its 2^bits entries.
    std::vector<float> colourMap;
    if (palette) {
        std::uint16_t *r = nullptr, *g = nullptr, *b = nullptr;
        if (TIFFGetField(t, TIFFTAG_COLORMAP, &r, &g, &b) != 1 || !r || !g || !b)
            throw fail("a palette image without a colour map");
        const std::uint16_t* map = channel == 0 ? r : channel == 1 ? g : b;
        colourMap.resize(std::size_t{1} << bits);
        for (std::size_t i = 0; i < colourMap.size(); ++i) colourMap[i] = static_cast<float>(map[i]) / 65535.0f;
    }

    const bool contig = planar == PLANARCONFIG_CONTIG || spp == 1;
    const std::size_t bytesPerSample = bits / 8u;
    const std::size_t stride = contig ? spp : 1; // samples per pixel in the decoded buffers
    const std::size_t offset = contig ? static_cast<std::size_t>(sample) : 0;
    const std::size_t w = width, h = height;
    const std::string channelName = std::to_string(channel);
    const double integerMax = std::ldexp(1.0, bits) - 1.0;

    HeightImage img;
    img.width = static_cast<int>(w);
    img.height = static_cast<int>(h);
    img.values.assign(w * h, 0.0f);
    // Converts the sample at p (native byte order: libtiff swaps) to the value of pixel i.
    const auto store = [&](const unsigned char* p, std::size_t i) {
        double v = 0;
        if (floating) {
            if (bits == 16) {
                std::uint16_t u;
                std::memcpy(&u, p, 2);
                Imath::half sampleHalf;
                sampleHalf.setBits(u);
                v = static_cast<double>(static_cast<float>(sampleHalf));
            } else if (bits == 32) {
                float f;
                std::memcpy(&f, p, 4);
                v = static_cast<double>(f);
            } else {
                std::memcpy(&v, p, 8);
            }
            if (!std::isfinite(v)) throw fail(nonFiniteSample(i, w, channelName, v));
            if (std::abs(v) > static_cast<double>(std::numeric_limits<float>::max()))
                throw fail("pixel (" + std::to_string(i % w) + ", " + std::to_string(i / w) + ") of channel '" +
                           channelName + "' is outside the float range");
            img.values[i] = static_cast<float>(v);
            return;
        }
        std::uint32_t u = 0;
        if (bits == 8) {
            u = *p;
        } else if (bits == 16) {
            std::uint16_t u16;
            std::memcpy(&u16, p, 2);
            u = u16;
        } else {
            std::memcpy(&u, p, 4);
        }
        img.values[i] = palette ? colourMap[u] : static_cast<float>(static_cast<double>(u) / integerMax);
    };

    if (!TIFFIsTiled(t)) {
        const std::uint64_t rowBytes = std::uint64_t{w} * stride * bytesPerSample;
        if (static_cast<std::uint64_t>(TIFFScanlineSize64(t)) != rowBytes)
            throw libtiffError("unexpected row size " + std::to_string(TIFFScanlineSize64(t)) + " (expected " +
                               std::to_string(rowBytes) + " bytes)");
        std::vector<unsigned char> row(static_cast<std::size_t>(rowBytes));
        for (std::uint32_t y = 0; y < height; ++y) {
            if (TIFFReadScanline(t, row.data(), y, static_cast<std::uint16_t>(contig ? 0 : sample)) != 1)
                throw libtiffError("cannot read row " + std::to_string(y));
            for (std::size_t x = 0; x < w; ++x) store(row.data() + (x * stride + offset) * bytesPerSample, y * w + x);
        }
    } else {
        std::uint32_t tileWidth = 0, tileHeight = 0;
        if (TIFFGetField(t, TIFFTAG_TILEWIDTH, &tileWidth) != 1 || TIFFGetField(t, TIFFTAG_TILELENGTH, &tileHeight) != 1 ||
            tileWidth == 0 || tileHeight == 0)
            throw fail("a tiled image without a valid tile size");
        const std::uint64_t tileBytes = std::uint64_t{tileWidth} * tileHeight * stride * bytesPerSample;
        const std::uint64_t imageBytes = std::uint64_t{w} * h * stride * bytesPerSample;
        if (tileBytes > std::max<std::uint64_t>(imageBytes, std::uint64_t{64} << 20))
            throw fail("tiles of " + std::to_string(tileWidth) + " x " + std::to_string(tileHeight) +
                       " are far larger than the image");
        if (static_cast<std::uint64_t>(TIFFTileSize64(t)) != tileBytes)
            throw libtiffError("unexpected tile size " + std::to_string(TIFFTileSize64(t)) + " (expected " +
                               std::to_string(tileBytes) + " bytes)");
        std::vector<unsigned char> tile(static_cast<std::size_t>(tileBytes));
        for (std::uint32_t ty = 0; ty < height; ty += std::min(tileHeight, height - ty))
            for (std::uint32_t tx = 0; tx < width; tx += std::min(tileWidth, width - tx)) {
                const std::uint32_t index = TIFFComputeTile(t, tx, ty, 0, static_cast<std::uint16_t>(contig ? 0 : sample));
                if (TIFFReadEncodedTile(t, index, tile.data(), static_cast<tmsize_t>(tileBytes)) !=
                    static_cast<tmsize_t>(tileBytes))
                    throw libtiffError("cannot read the tile at (" + std::to_string(tx) + ", " + std::to_string(ty) + ")");
                const std::size_t rows = std::min<std::size_t>(tileHeight, h - ty);
                const std::size_t cols = std::min<std::size_t>(tileWidth, w - tx);
                for (std::size_t y = 0; y < rows; ++y)
                    for (std::size_t x = 0; x < cols; ++x)
                        store(tile.data() + ((y * tileWidth + x) * stride + offset) * bytesPerSample,
                              (ty + y) * w + tx + x);
            }
    }
    if (info) {
        info->format = ImageFileFormat::Tiff;
        info->bits = bits;
        info->floatSamples = floating;
        info->normalised = !floating;
        info->channels = channelCount;
        info->channel = channelName;
    }
    return img;
}

} // namespace detail

/// Reads one channel of a PNG, OpenEXR or TIFF file as a height image, the format told by the
/// file's first bytes (see the top of this file for what is read and how values are scaled).
/// options.maxSide (at most kMaxHeightImageSize) is checked from the header before any pixel
/// is allocated. If info is not null, it receives the format, sample type and channel read.
/// Throws FileError naming path and the reason: cannot open, not a regular file, larger than
/// kMaxImageFileBytes (PNG: detail::kMaxPngFileBytes), not a PNG, EXR or TIFF file, larger than
/// maxSide per side, an asked channel that is not in the file (naming those that are), a
/// non-finite float sample (naming the pixel and channel), an unsupported kind of image (deep
/// or subsampled EXR; TIFF sample formats, depths, photometric interpretations and orientations
/// of the top of this file), and every error OpenEXR, libtiff or libpng reports (truncated or
/// corrupt files).
inline HeightImage readHeightImage(const std::string& path, const HeightReadOptions& options = {},
                                   HeightImageInfo* info = nullptr) {
    const auto fail = [&](const std::string& why) { return FileError("height image '" + path + "': " + why); };
    const auto readPng = [&]() {
        if (!options.channel.empty() && options.channel != "0" && options.channel != "Y")
            throw fail("PNG heights are grey: channel '" + detail::excerpt(options.channel) +
                       "' cannot be chosen (use \"\", \"0\" or \"Y\")");
        unsigned char head[26] = {};
        const std::size_t n = detail::readFileHead(path, head, sizeof head);
        HeightImage img = readHeightPng(path, options.maxSide);
        if (info) {
            const int colourType = n >= 26 ? head[25] : 0;
            info->format = ImageFileFormat::Png;
            info->bits = n >= 26 ? head[24] : 0;
            info->floatSamples = false;
            info->normalised = true;
            info->channels = colourType == 2 ? 3 : colourType == 4 ? 2 : colourType == 6 ? 4 : 1;
            info->channel = "0";
        }
        return img;
    };

    unsigned char head[8] = {};
    ImageFileFormat format = ImageFileFormat::Png;
    const std::size_t n = detail::readFileHead(path, head, sizeof head);
    if (detail::imageFormatOf(head, n, &format) && format == ImageFileFormat::Png) return readPng();

    const std::vector<unsigned char> bytes = detail::readFileBytes(path, "height image", kMaxImageFileBytes);
    if (!detail::imageFormatOf(bytes.data(), bytes.size(), &format)) {
        if (bytes.empty()) throw fail("is empty; not a PNG, EXR or TIFF file");
        std::string start;
        for (std::size_t i = 0; i < std::min<std::size_t>(bytes.size(), 4); ++i) {
            char hex[4];
            std::snprintf(hex, sizeof hex, " %02x", bytes[i]);
            start += hex;
        }
        throw fail("is not a PNG, EXR or TIFF file (it starts with bytes" + start + ")");
    }
    switch (format) {
    case ImageFileFormat::Png: return readPng(); // it became one since the first look
    case ImageFileFormat::Exr: return detail::readHeightExr(bytes, path, fail, options, info);
    case ImageFileFormat::Tiff: return detail::readHeightTiff(bytes, path, fail, options, info);
    }
    throw fail("unknown format");
}

/// Writes img as an OpenEXR file with one channel "Y" (half or 32-bit float, ZIP compression,
/// data and display window (0, 0) - (width - 1, height - 1)), values as they are (half: rounded
/// to the nearest half), atomically: a failed write leaves an existing file untouched. Throws
/// ArgumentError (nothing written) unless 1 <= width, height <= kMaxHeightImageSize,
/// values.size() == width * height and every value is finite (and, for half, at most 65504 in
/// magnitude; the message names the first bad texel); FileError if the file cannot be written
/// or OpenEXR fails.
inline void writeHeightExr(const std::string& path, const HeightImage& img, bool halfSamples = false) {
    const std::string who = "writeHeightExr('" + path + "')";
    detail::checkImageToWrite(img, who);
    const std::size_t w = static_cast<std::size_t>(img.width);
    if (halfSamples)
        for (std::size_t i = 0; i < img.values.size(); ++i)
            if (std::abs(img.values[i]) > detail::kHalfMax)
                throw ArgumentError(who + ": texel (" + std::to_string(i % w) + ", " + std::to_string(i / w) + ") value " +
                                    std::to_string(img.values[i]) + " is beyond the half range (65504)");
    std::vector<unsigned char> encoded;
    try {
        Imf::Header header(img.width, img.height);
        header.compression() = Imf::ZIP_COMPRESSION;
        header.channels().insert("Y", Imf::Channel(halfSamples ? Imf::HALF : Imf::FLOAT));
        detail::ExrMemoryOStream stream(encoded, path);
        Imf::OutputFile file(stream, header); // its destructor writes the offset table
        // OpenEXR converts on reading only: half channels are written from halves.
        std::vector<Imath::half> halves;
        if (halfSamples) halves.assign(img.values.begin(), img.values.end());
        Imf::FrameBuffer frame;
        frame.insert("Y", halfSamples ? Imf::Slice::Make(Imf::HALF, halves.data(), header.dataWindow())
                                      : Imf::Slice::Make(Imf::FLOAT, img.values.data(), header.dataWindow()));
        file.setFrameBuffer(frame);
        file.writePixels(img.height);
    } catch (const std::exception& e) {
        throw FileError("cannot write height image '" + path + "': OpenEXR: " + e.what());
    }
    detail::writeFileAtomically(path, encoded, "height image");
}

/// Writes img as a TIFF file of one sample per pixel (grey, min-is-black, top-left, Deflate
/// compression with a predictor, strips of about 64 KiB), atomically: a failed write leaves an
/// existing file untouched. bits 8, 16 or 32 with floatSamples false: unsigned integers, value
/// v stored as round(v * (2^bits - 1)); bits 16 (half) or 32 with floatSamples true: the values
/// as they are (half: rounded to the nearest half). Throws ArgumentError (nothing written) for
/// another bits/floatSamples pair, unless 1 <= width, height <= kMaxHeightImageSize and
/// values.size() == width * height, and for a value that is not finite, outside [0, 1] for
/// integers or beyond 65504 in magnitude for half (the message names the first bad texel);
/// FileError if the file cannot be written or libtiff fails.
inline void writeHeightTiff(const std::string& path, const HeightImage& img, int bits, bool floatSamples) {
    const std::string who = "writeHeightTiff('" + path + "')";
    if (floatSamples ? (bits != 16 && bits != 32) : (bits != 8 && bits != 16 && bits != 32))
        throw ArgumentError(who + ": " + std::to_string(bits) + "-bit " + (floatSamples ? "float" : "integer") +
                            " samples are not written (8, 16 or 32 bits for integers; 16 or 32 for floats)");
    detail::checkImageToWrite(img, who);
    const std::size_t w = static_cast<std::size_t>(img.width), h = static_cast<std::size_t>(img.height);
    const std::size_t bytesPerSample = static_cast<std::size_t>(bits) / 8;
    const double scale = std::ldexp(1.0, bits) - 1.0;
    std::vector<unsigned char> pixels(w * h * bytesPerSample);
    for (std::size_t i = 0; i < w * h; ++i) {
        const float v = img.values[i];
        unsigned char* p = pixels.data() + i * bytesPerSample;
        const auto bad = [&](const char* why) {
            return ArgumentError(who + ": texel (" + std::to_string(i % w) + ", " + std::to_string(i / w) + ") value " +
                                 std::to_string(v) + why);
        };
        if (floatSamples && bits == 32) {
            std::memcpy(p, &v, 4);
        } else if (floatSamples) {
            if (std::abs(v) > detail::kHalfMax) throw bad(" is beyond the half range (65504)");
            const std::uint16_t u = Imath::half(v).bits();
            std::memcpy(p, &u, 2);
        } else {
            if (!(v >= 0.0f && v <= 1.0f)) throw bad(" is outside [0, 1]");
            const auto q = static_cast<std::uint32_t>(std::llround(static_cast<double>(v) * scale));
            if (bits == 8) {
                *p = static_cast<unsigned char>(q);
            } else if (bits == 16) {
                const auto u = static_cast<std::uint16_t>(q);
                std::memcpy(p, &u, 2);
            } else {
                std::memcpy(p, &q, 4);
            }
        }
    }

    std::vector<unsigned char> encoded;
    encoded.reserve(pixels.size() / 2 + 1024);
    detail::TiffIo io;
    io.out = &encoded;
    io.name = path.c_str();
    const auto fail = [&](const std::string& what) {
        return FileError("cannot write height image '" + path + "': " + what +
                         (io.message[0] ? std::string(": ") + io.message : std::string()));
    };
    {
        const detail::TiffPtr tif = detail::tiffOpen(io, "w", 0);
        if (!tif) throw fail("libtiff cannot create it");
        TIFF* t = tif.get();
        const std::size_t rowBytes = w * bytesPerSample;
        const auto rowsPerStrip = static_cast<std::uint32_t>(std::clamp<std::size_t>(65536 / rowBytes, 1, h));
        const bool deflate = TIFFIsCODECConfigured(COMPRESSION_ADOBE_DEFLATE) != 0;
        const bool ok =
            TIFFSetField(t, TIFFTAG_IMAGEWIDTH, static_cast<std::uint32_t>(w)) == 1 &&
            TIFFSetField(t, TIFFTAG_IMAGELENGTH, static_cast<std::uint32_t>(h)) == 1 &&
            TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1) == 1 && TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, bits) == 1 &&
            TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, floatSamples ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT) == 1 &&
            TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK) == 1 &&
            TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG) == 1 &&
            TIFFSetField(t, TIFFTAG_ORIENTATION, ORIENTATION_TOPLEFT) == 1 &&
            TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, rowsPerStrip) == 1 &&
            TIFFSetField(t, TIFFTAG_COMPRESSION, deflate ? COMPRESSION_ADOBE_DEFLATE : COMPRESSION_NONE) == 1 &&
            (!deflate ||
             TIFFSetField(t, TIFFTAG_PREDICTOR, floatSamples ? PREDICTOR_FLOATINGPOINT : PREDICTOR_HORIZONTAL) == 1);
        if (!ok) throw fail("libtiff refused a tag");
        for (std::size_t row = 0, strip = 0; row < h; row += rowsPerStrip, ++strip) {
            const std::size_t rows = std::min<std::size_t>(rowsPerStrip, h - row);
            // libtiff's predictor works in place: it gets a copy of the strip.
            std::vector<unsigned char> data(pixels.begin() + static_cast<std::ptrdiff_t>(row * rowBytes),
                                            pixels.begin() + static_cast<std::ptrdiff_t>((row + rows) * rowBytes));
            if (TIFFWriteEncodedStrip(t, static_cast<std::uint32_t>(strip), data.data(),
                                      static_cast<tmsize_t>(data.size())) < 0)
                throw fail("cannot encode strip " + std::to_string(strip));
        }
        if (TIFFFlush(t) != 1) throw fail("cannot finish the file");
    }
    if (io.message[0]) throw fail("libtiff");
    detail::writeFileAtomically(path, encoded, "height image");
}

// ------------------------------------------------------------------------------------------
// UDIM tile sets

/// The height images of a UDIM set, by UDIM number (1001 + u + 10 v), each with its own size.
struct UdimImages {
    std::map<int, std::shared_ptr<const HeightImage>> tiles;
    /// The pattern the set was read from.
    std::string pattern;
};

/// The UDIM tokens a file name pattern may hold: "<UDIM>" (Mari, Substance), "<udim>" and
/// "%(UDIM)d" (Houdini, Python style), each standing for the four digits of the tile's number.
inline constexpr const char* kUdimTokens[] = {"<UDIM>", "<udim>", "%(UDIM)d"};

/// True if path holds a UDIM token (kUdimTokens).
inline bool isUdimPattern(const std::string& path) {
    return std::any_of(std::begin(kUdimTokens), std::end(kUdimTokens),
                       [&](const char* token) { return path.find(token) != std::string::npos; });
}

/// The UDIM number of tile (uTile, vTile): 1001 + uTile + 10 vTile. Throws ArgumentError
/// unless 0 <= uTile < 10 and 0 <= vTile < 10 (the range readUdimImages reads).
inline int udimOf(int uTile, int vTile) {
    if (uTile < 0 || uTile >= 10 || vTile < 0 || vTile >= 10)
        throw ArgumentError("udimOf: tile (" + std::to_string(uTile) + ", " + std::to_string(vTile) +
                            ") is outside [0, 10) x [0, 10)");
    return 1001 + uTile + 10 * vTile;
}

namespace detail {
// The pattern's token and where it is in the pattern; throws ArgumentError (naming `who`)
// unless there is exactly one token, in the file name (not in a folder name).
inline std::pair<std::size_t, std::size_t> udimToken(const std::string& pattern, const char* who) {
    std::size_t at = std::string::npos, length = 0, count = 0;
    for (const char* token : kUdimTokens)
        for (std::size_t p = pattern.find(token); p != std::string::npos; p = pattern.find(token, p + 1)) {
            at = p;
            length = std::strlen(token);
            ++count;
        }
    if (count != 1)
        throw ArgumentError(std::string(who) + ": '" + pattern + "' " +
                            (count == 0 ? "holds no UDIM token (<UDIM>, <udim> or %(UDIM)d)"
                                        : "holds more than one UDIM token"));
    if (pattern.find('/', at) != std::string::npos)
        throw ArgumentError(std::string(who) + ": '" + pattern + "' has its UDIM token in a folder name");
    return {at, length};
}
} // namespace detail

/// The file of tile `udim` of a UDIM pattern: the token replaced by the four digits. Throws
/// ArgumentError unless the pattern holds exactly one token, in its file name, and 1001 <=
/// udim <= 1100.
inline std::string udimPath(const std::string& pattern, int udim) {
    const auto token = detail::udimToken(pattern, "udimPath");
    if (udim < 1001 || udim > 1100)
        throw ArgumentError("udimPath: UDIM " + std::to_string(udim) + " is outside [1001, 1100]");
    return pattern.substr(0, token.first) + std::to_string(udim) + pattern.substr(token.first + token.second);
}

/// Reads every tile of a UDIM set: the files of the pattern's folder whose names are the
/// pattern's file name with its token replaced by four digits of a number in [1001, 1100]
/// (other names, and numbers outside that range, are left alone), each with readHeightImage
/// and the same options; each tile may have its own size. Throws ArgumentError unless the
/// pattern holds exactly one UDIM token, in its file name; FileError naming the pattern and the
/// folder if the folder does not exist or is not a folder, or no file matches; and the
/// FileError of readHeightImage for a tile that cannot be read.
inline UdimImages readUdimImages(const std::string& pattern, const HeightReadOptions& options = {}) {
    namespace fs = std::filesystem;
    const auto token = detail::udimToken(pattern, "readUdimImages");
    const std::size_t slash = pattern.rfind('/', token.first);
    const std::string folder = slash == std::string::npos ? "." : slash == 0 ? "/" : pattern.substr(0, slash);
    const std::size_t nameStart = slash == std::string::npos ? 0 : slash + 1;
    const std::string prefix = pattern.substr(nameStart, token.first - nameStart);
    const std::string suffix = pattern.substr(token.first + token.second);
    const auto fail = [&](const std::string& why) {
        return FileError("UDIM height images '" + pattern + "': folder '" + folder + "' " + why);
    };
    std::error_code ec;
    const fs::file_status st = fs::status(folder, ec);
    if (ec && st.type() != fs::file_type::not_found) throw fail("cannot be read: " + ec.message());
    if (st.type() == fs::file_type::not_found) throw fail("does not exist");
    if (st.type() != fs::file_type::directory) throw fail("is not a folder (" + detail::notRegularFile(st) + ")");

    std::map<int, std::string> files;
    fs::directory_iterator it(folder, ec);
    if (ec) throw fail("cannot be listed: " + ec.message());
    for (; it != fs::directory_iterator(); it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.size() != prefix.size() + 4 + suffix.size() || name.compare(0, prefix.size(), prefix) != 0 ||
            name.compare(prefix.size() + 4, suffix.size(), suffix) != 0)
            continue;
        int udim = 0;
        bool digits = true;
        for (std::size_t i = prefix.size(); i < prefix.size() + 4; ++i) {
            digits = digits && name[i] >= '0' && name[i] <= '9';
            udim = udim * 10 + (name[i] - '0');
        }
        if (digits && udim >= 1001 && udim <= 1100)
            files[udim] = slash == std::string::npos ? name : (fs::path(folder) / name).string();
    }
    if (ec) throw fail("cannot be listed: " + ec.message());
    if (files.empty())
        throw fail("holds no file '" + prefix + "<1001..1100>" + suffix + "' of the set");
    UdimImages set;
    set.pattern = pattern;
    for (const auto& [udim, file] : files)
        set.tiles.emplace(udim, std::make_shared<const HeightImage>(readHeightImage(file, options)));
    return set;
}

/// The height map a path names, as surface/map_source.h places it: a UDIM set
/// (readUdimImages) when the path holds a UDIM token, else one image (readHeightImage) under
/// key 0. Throws as those.
inline HeightMaps readHeightMaps(const std::string& path, const HeightReadOptions& options = {}) {
    HeightMaps maps;
    if (isUdimPattern(path)) {
        maps.udim = true;
        maps.images = readUdimImages(path, options).tiles;
    } else {
        maps.images[0] = std::make_shared<const HeightImage>(readHeightImage(path, options));
    }
    return maps;
}

} // namespace dispmap
