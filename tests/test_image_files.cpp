// Height images from EXR, TIFF and PNG files (io/image_files.h): round trips of every sample
// type, channel selection, the EXR and TIFF layouts tools write (data windows, tiles, mip maps,
// multi-part, planes, palettes, big-endian), errors before large allocations, damaged files,
// non-finite samples, and UDIM sets.
#include <catch2/catch.hpp>

#include "test_files.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfMultiPartOutputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfOutputPart.h>
#include <OpenEXR/ImfPartType.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <png.h>
#include <tiffio.h>

#include "dispmap/io/image_files.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_test_image_files {

using dispmap::ArgumentError;
using dispmap::FileError;
using dispmap::HeightImage;
using dispmap::HeightImageInfo;
using dispmap::HeightReadOptions;
using dispmap::ImageFileFormat;
using dispmap::readHeightImage;
using dmtest::readBytes;
using dmtest::writeBytes;

namespace {

struct TempDir : dmtest::TempDir {
    TempDir() : dmtest::TempDir("dispmap_image_files_test_") {}
};

// 0.5 + 0.4 sin(..) cos(..): smooth, in [0.1, 0.9], every texel different.
HeightImage analytic(int width, int height) {
    HeightImage img;
    img.width = width;
    img.height = height;
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            img.values.push_back(static_cast<float>(0.5 + 0.4 * std::sin(0.07 * x + 0.3) * std::cos(0.11 * y - 0.2)));
    return img;
}

HeightImage constant(int width, int height, float value) {
    HeightImage img;
    img.width = width;
    img.height = height;
    img.values.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), value);
    return img;
}

double maxAbsError(const HeightImage& a, const HeightImage& b) {
    REQUIRE(a.width == b.width);
    REQUIRE(a.height == b.height);
    REQUIRE(a.values.size() == b.values.size());
    double e = 0;
    for (std::size_t i = 0; i < a.values.size(); ++i)
        e = std::max(e, std::abs(static_cast<double>(a.values[i]) - static_cast<double>(b.values[i])));
    return e;
}

// The message of the FileError f throws (the test fails if it throws nothing or another type).
std::string fileErrorOf(const std::function<void()>& f) {
    REQUIRE_THROWS_AS(f(), FileError);
    try {
        f();
    } catch (const FileError& e) {
        return e.what();
    }
    return "";
}

// REQUIRE that reading path throws a FileError whose message names the file and `mentions`.
void requireReadError(const std::string& path, const std::string& mentions, const HeightReadOptions& options = {}) {
    const std::string message = fileErrorOf([&] { readHeightImage(path, options); });
    INFO(message);
    CHECK(message.find(path) != std::string::npos);
    CHECK(message.find(mentions) != std::string::npos);
}

// Writes an EXR with OpenEXR directly: one FLOAT, HALF or UINT channel per entry of
// `channels` (values row by row over the data window; UINT: truncated), scan lines, ZIP.
void writeExr(const std::string& path, const Imath::Box2i& window, const std::map<std::string, std::vector<float>>& channels,
              Imf::PixelType type = Imf::FLOAT) {
    Imf::Header header(window, window);
    header.compression() = Imf::ZIP_COMPRESSION;
    Imf::FrameBuffer frame;
    // OpenEXR writes each channel from samples of its own type.
    std::vector<std::vector<Imath::half>> halves;
    std::vector<std::vector<unsigned>> uints;
    halves.reserve(channels.size());
    uints.reserve(channels.size());
    for (const auto& [name, values] : channels) {
        header.channels().insert(name, Imf::Channel(type));
        if (type == Imf::HALF) {
            halves.emplace_back(values.begin(), values.end());
            frame.insert(name, Imf::Slice::Make(type, halves.back().data(), window));
        } else if (type == Imf::UINT) {
            uints.emplace_back();
            for (const float v : values) uints.back().push_back(static_cast<unsigned>(v));
            frame.insert(name, Imf::Slice::Make(type, uints.back().data(), window));
        } else {
            frame.insert(name, Imf::Slice::Make(type, values.data(), window));
        }
    }
    Imf::OutputFile file(path.c_str(), header);
    file.setFrameBuffer(frame);
    file.writePixels(window.max.y - window.min.y + 1);
}

Imath::Box2i windowOf(int width, int height) { return Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(width - 1, height - 1)); }

// Writes a tiled, mip-mapped EXR (one FLOAT channel "Y"): level 0 is img, the others 7.
void writeTiledExr(const std::string& path, const HeightImage& img, int tileSide) {
    Imf::Header header(img.width, img.height);
    header.channels().insert("Y", Imf::Channel(Imf::FLOAT));
    header.setTileDescription(Imf::TileDescription(static_cast<unsigned>(tileSide), static_cast<unsigned>(tileSide),
                                                   Imf::MIPMAP_LEVELS, Imf::ROUND_DOWN));
    Imf::TiledOutputFile file(path.c_str(), header);
    for (int level = 0; level < file.numLevels(); ++level) {
        HeightImage levelImage = img;
        if (level > 0) {
            levelImage.width = file.levelWidth(level);
            levelImage.height = file.levelHeight(level);
            levelImage.values.assign(static_cast<std::size_t>(levelImage.width * levelImage.height), 7.0f);
        }
        Imf::FrameBuffer frame;
        frame.insert("Y", Imf::Slice::Make(Imf::FLOAT, levelImage.values.data(), file.dataWindowForLevel(level)));
        file.setFrameBuffer(frame);
        file.writeTiles(0, file.numXTiles(level) - 1, 0, file.numYTiles(level) - 1, level);
    }
}

// A TIFF written with libtiff directly (LZW, not the Deflate of writeHeightTiff).
struct TiffSpec {
    int width = 0, height = 0, samples = 1, bits = 8;
    int format = SAMPLEFORMAT_UINT;
    int photometric = PHOTOMETRIC_MINISBLACK;
    bool separate = false;    // PLANARCONFIG_SEPARATE
    int tile = 0;             // tile side (a multiple of 16), 0 for strips of 7 rows
    int orientation = ORIENTATION_TOPLEFT;
    bool alpha = false;       // the last sample is unassociated alpha
    bool bigTiff = false;
    std::vector<std::uint16_t> colourMap; // palette: R, G, B arrays of 2^bits entries each
};

// Sample c of pixel (x, y) as stored: raw integers for integer formats, values for floats.
using SampleFn = std::function<double(int x, int y, int c)>;

void putSample(unsigned char* p, const TiffSpec& s, double v) {
    if (s.format == SAMPLEFORMAT_IEEEFP) {
        if (s.bits == 16) {
            const std::uint16_t u = Imath::half(static_cast<float>(v)).bits();
            std::memcpy(p, &u, 2);
        } else {
            const auto f = static_cast<float>(v);
            std::memcpy(p, &f, 4);
        }
    } else if (s.format == SAMPLEFORMAT_INT) {
        const auto i = static_cast<std::int16_t>(v);
        std::memcpy(p, &i, 2);
    } else if (s.bits == 8) {
        *p = static_cast<unsigned char>(v);
    } else if (s.bits == 16) {
        const auto u = static_cast<std::uint16_t>(v);
        std::memcpy(p, &u, 2);
    } else {
        const auto u = static_cast<std::uint32_t>(v);
        std::memcpy(p, &u, 4);
    }
}

void writeTiff(const std::string& path, const TiffSpec& s, const SampleFn& value) {
    TIFF* tif = TIFFOpen(path.c_str(), s.bigTiff ? "w8" : "w");
    REQUIRE(tif);
    const auto u32 = [](int v) { return static_cast<std::uint32_t>(v); };
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, u32(s.width));
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, u32(s.height));
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, s.samples);
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, s.bits);
    TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, s.format);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, s.photometric);
    TIFFSetField(tif, TIFFTAG_PLANARCONFIG, s.separate ? PLANARCONFIG_SEPARATE : PLANARCONFIG_CONTIG);
    TIFFSetField(tif, TIFFTAG_ORIENTATION, s.orientation);
    TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_LZW);
    if (s.alpha) {
        const std::uint16_t extra[] = {EXTRASAMPLE_UNASSALPHA};
        TIFFSetField(tif, TIFFTAG_EXTRASAMPLES, 1, extra);
    }
    if (!s.colourMap.empty()) {
        const std::size_t n = s.colourMap.size() / 3;
        TIFFSetField(tif, TIFFTAG_COLORMAP, s.colourMap.data(), s.colourMap.data() + n, s.colourMap.data() + 2 * n);
    }
    const std::size_t bytes = static_cast<std::size_t>(s.bits) / 8;
    const int planes = s.separate ? s.samples : 1, perPixel = s.separate ? 1 : s.samples;
    if (s.tile == 0) {
        TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, 7u);
        std::vector<unsigned char> row(static_cast<std::size_t>(s.width * perPixel) * bytes);
        for (int plane = 0; plane < planes; ++plane)
            for (int y = 0; y < s.height; ++y) {
                for (int x = 0; x < s.width; ++x)
                    for (int k = 0; k < perPixel; ++k)
                        putSample(row.data() + static_cast<std::size_t>(x * perPixel + k) * bytes, s,
                                  value(x, y, s.separate ? plane : k));
                REQUIRE(TIFFWriteScanline(tif, row.data(), u32(y), static_cast<std::uint16_t>(plane)) == 1);
            }
    } else {
        TIFFSetField(tif, TIFFTAG_TILEWIDTH, u32(s.tile));
        TIFFSetField(tif, TIFFTAG_TILELENGTH, u32(s.tile));
        std::vector<unsigned char> tile(static_cast<std::size_t>(s.tile * s.tile * perPixel) * bytes);
        for (int plane = 0; plane < planes; ++plane)
            for (int ty = 0; ty < s.height; ty += s.tile)
                for (int tx = 0; tx < s.width; tx += s.tile) {
                    std::fill(tile.begin(), tile.end(), 0xAB); // padding past the image edges
                    for (int y = ty; y < std::min(ty + s.tile, s.height); ++y)
                        for (int x = tx; x < std::min(tx + s.tile, s.width); ++x)
                            for (int k = 0; k < perPixel; ++k)
                                putSample(tile.data() + static_cast<std::size_t>(((y - ty) * s.tile + x - tx) * perPixel + k) *
                                                            bytes,
                                          s, value(x, y, s.separate ? plane : k));
                    REQUIRE(TIFFWriteTile(tif, tile.data(), u32(tx), u32(ty), 0, static_cast<std::uint16_t>(plane)) > 0);
                }
    }
    TIFFClose(tif);
}

// A TIFF built byte by byte: one IFD of `entries` (tag, type 3 SHORT or 4 LONG, count 1,
// value), then `data`; a StripOffsets entry (273) gets the offset of data.
struct IfdEntry {
    std::uint16_t tag, type;
    std::uint32_t value;
};
std::vector<unsigned char> handBuiltTiff(bool bigEndian, const std::vector<IfdEntry>& entries,
                                         const std::vector<unsigned char>& data) {
    std::vector<unsigned char> b;
    const auto put = [&](std::uint32_t v, int n) {
        for (int i = 0; i < n; ++i) {
            const int shift = bigEndian ? 8 * (n - 1 - i) : 8 * i;
            b.push_back(static_cast<unsigned char>((v >> shift) & 0xFF));
        }
    };
    b.push_back(bigEndian ? 'M' : 'I');
    b.push_back(bigEndian ? 'M' : 'I');
    put(42, 2);
    put(8, 4);
    put(static_cast<std::uint32_t>(entries.size()), 2);
    const auto dataAt = static_cast<std::uint32_t>(8 + 2 + 12 * entries.size() + 4);
    for (const IfdEntry& e : entries) {
        put(e.tag, 2);
        put(e.type, 2);
        put(1, 4);
        const std::uint32_t v = e.tag == 273 ? dataAt : e.value;
        if (e.type == 3) { // a SHORT sits in the first two bytes of the value field
            put(v, 2);
            put(0, 2);
        } else {
            put(v, 4);
        }
    }
    put(0, 4); // no next IFD
    b.insert(b.end(), data.begin(), data.end());
    return b;
}

// The IFD of a grey, uncompressed, single-strip TIFF.
std::vector<IfdEntry> greyIfd(std::uint32_t width, std::uint32_t height, std::uint16_t bits, std::uint32_t dataBytes) {
    return {{256, 4, width}, {257, 4, height}, {258, 3, bits}, {259, 3, 1},         {262, 3, 1},
            {273, 4, 0},     {277, 3, 1},      {278, 4, height}, {279, 4, dataBytes}};
}

// Sets the data window stored in an EXR file's header.
void patchDataWindow(std::vector<unsigned char>& bytes, std::int32_t xMin, std::int32_t yMin, std::int32_t xMax,
                     std::int32_t yMax) {
    static const char key[] = "dataWindow\0box2i"; // both names with their terminating nulls
    const auto it = std::search(bytes.begin(), bytes.end(), key, key + sizeof key);
    REQUIRE(it != bytes.end());
    const auto at = static_cast<std::size_t>(it - bytes.begin()) + sizeof key + 4; // past the size
    const std::int32_t box[4] = {xMin, yMin, xMax, yMax};
    for (int i = 0; i < 4; ++i) {
        std::uint32_t u;
        std::memcpy(&u, &box[i], 4);
        for (int k = 0; k < 4; ++k)
            bytes[at + static_cast<std::size_t>(4 * i + k)] = static_cast<unsigned char>((u >> (8 * k)) & 0xFF);
    }
}

void writePng8(const std::string& path, int width, int height, const std::vector<unsigned char>& grey) {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    image.width = static_cast<png_uint_32>(width);
    image.height = static_cast<png_uint_32>(height);
    image.format = PNG_FORMAT_GRAY;
    REQUIRE(png_image_write_to_file(&image, path.c_str(), 0, grey.data(), 0, nullptr) != 0);
}

} // namespace

TEST_CASE("image files: EXR round trips, float and half", "[image_files]") {
    TempDir dir;
    const HeightImage img = analytic(257, 129);
    HeightImageInfo info;
    SECTION("float: exact") {
        dispmap::writeHeightExr(dir.file("h.exr"), img);
        const HeightImage back = readHeightImage(dir.file("h.exr"), {}, &info);
        REQUIRE(back.values == img.values); // float samples are stored as they are
        CHECK(info.format == ImageFileFormat::Exr);
        CHECK(info.bits == 32);
        CHECK(info.floatSamples);
        CHECK(!info.normalised);
        CHECK(info.channels == 1);
        CHECK(info.channel == "Y");
    }
    SECTION("half: relative error at most 2^-11") {
        dispmap::writeHeightExr(dir.file("h.exr"), img, true);
        const HeightImage back = readHeightImage(dir.file("h.exr"), {}, &info);
        REQUIRE(back.width == 257);
        REQUIRE(back.height == 129);
        // Rounding to half's 11-bit significand (values in [0.1, 0.9] are normal halves).
        for (std::size_t i = 0; i < img.values.size(); ++i)
            REQUIRE(std::abs(back.values[i] - img.values[i]) <= std::ldexp(std::abs(img.values[i]), -11));
        CHECK(info.bits == 16);
        CHECK(info.floatSamples);
    }
    SECTION("the format comes from the bytes, not the name") {
        dispmap::writeHeightExr(dir.file("h.png"), img);
        REQUIRE(readHeightImage(dir.file("h.png"), {}, &info).values == img.values); // exact as above
        CHECK(info.format == ImageFileFormat::Exr);
    }
    SECTION("values outside [0, 1] are heights in scene units") {
        HeightImage wide = img;
        for (float& v : wide.values) v = (v - 0.5f) * 40.0f;
        dispmap::writeHeightExr(dir.file("h.exr"), wide);
        REQUIRE(readHeightImage(dir.file("h.exr")).values == wide.values); // float: exact
    }
}

TEST_CASE("image files: TIFF round trips, integer and float", "[image_files]") {
    TempDir dir;
    const HeightImage img = analytic(257, 129);
    const std::string path = dir.file("h.tif");
    HeightImageInfo info;
    // Quantisation to b bits (half a step) plus the float rounding of q / (2^b - 1) (2^-25 below 1).
    const auto quantised = [](int bits) { return 0.5 / (std::ldexp(1.0, bits) - 1.0) + std::ldexp(1.0, -24); };
    for (const int bits : {8, 16, 32}) {
        DYNAMIC_SECTION("unsigned " << bits << "-bit") {
            dispmap::writeHeightTiff(path, img, bits, false);
            const HeightImage back = readHeightImage(path, {}, &info);
            REQUIRE(maxAbsError(back, img) <= quantised(bits));
            CHECK(info.format == ImageFileFormat::Tiff);
            CHECK(info.bits == bits);
            CHECK(!info.floatSamples);
            CHECK(info.normalised);
            CHECK(info.channel == "0");
        }
    }
    SECTION("32-bit float: exact") {
        dispmap::writeHeightTiff(path, img, 32, true);
        REQUIRE(readHeightImage(path, {}, &info).values == img.values); // float samples as they are
        CHECK(info.floatSamples);
        CHECK(info.bits == 32);
    }
    SECTION("16-bit float: relative error at most 2^-11") {
        dispmap::writeHeightTiff(path, img, 16, true);
        const HeightImage back = readHeightImage(path, {}, &info);
        REQUIRE(back.values.size() == img.values.size());
        // Rounding to half's 11-bit significand, as for EXR half.
        for (std::size_t i = 0; i < img.values.size(); ++i)
            REQUIRE(std::abs(back.values[i] - img.values[i]) <= std::ldexp(std::abs(img.values[i]), -11));
        CHECK(info.bits == 16);
    }
    SECTION("the extremes 0 and 1 map to 0 and 2^b - 1") {
        const HeightImage ends = [] {
            HeightImage e = constant(2, 1, 0.0f);
            e.values[1] = 1.0f;
            return e;
        }();
        for (const int bits : {8, 16, 32}) {
            dispmap::writeHeightTiff(path, ends, bits, false);
            REQUIRE(readHeightImage(path).values == ends.values); // exact: 0 / m and m / m
        }
    }
}

TEST_CASE("image files: PNG through readHeightImage", "[image_files]") {
    TempDir dir;
    const HeightImage img = analytic(257, 129);
    HeightImageInfo info;
    SECTION("16-bit (writeHeightPng16)") {
        dispmap::writeHeightPng16(dir.file("h.png"), img);
        const HeightImage back = readHeightImage(dir.file("h.png"), {}, &info);
        // Half a 16-bit step, plus the float rounding of v / 65535.
        REQUIRE(maxAbsError(back, img) <= 0.5 / 65535 + std::ldexp(1.0, -24));
        CHECK(info.format == ImageFileFormat::Png);
        CHECK(info.bits == 16);
        CHECK(info.normalised);
        CHECK(info.channel == "0");
    }
    SECTION("8-bit (libpng's simplified writer)") {
        std::vector<unsigned char> grey;
        for (const float v : img.values) grey.push_back(static_cast<unsigned char>(std::lround(v * 255.0f)));
        writePng8(dir.file("h.png"), 257, 129, grey);
        const HeightImage back = readHeightImage(dir.file("h.png"), {}, &info);
        // Half an 8-bit step, plus the float rounding of v / 255.
        REQUIRE(maxAbsError(back, img) <= 0.5 / 255 + std::ldexp(1.0, -24));
        CHECK(info.bits == 8);
    }
    SECTION("PNG heights are grey: a colour channel cannot be asked") {
        dispmap::writeHeightPng16(dir.file("h.png"), img);
        HeightReadOptions options;
        options.channel = "Y";
        REQUIRE(readHeightImage(dir.file("h.png"), options).width == 257);
        options.channel = "G";
        requireReadError(dir.file("h.png"), "PNG heights are grey", options);
    }
}

TEST_CASE("image files: EXR channels", "[image_files]") {
    TempDir dir;
    const int w = 13, h = 9;
    std::vector<float> r, g, b;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            r.push_back(static_cast<float>(x) * 0.25f);
            g.push_back(static_cast<float>(y) * -2.0f);
            b.push_back(static_cast<float>(x * y) + 0.5f);
        }
    const std::string path = dir.file("rgb.exr");
    writeExr(path, windowOf(w, h), {{"R", r}, {"G", g}, {"B", b}});
    HeightReadOptions options;
    HeightImageInfo info;
    // Every value below is a small binary fraction, exact in float: comparisons are exact.
    SECTION("several channels, none Y: R") {
        REQUIRE(readHeightImage(path, options, &info).values == r);
        CHECK(info.channel == "R");
        CHECK(info.channels == 3);
    }
    SECTION("a channel by name") {
        options.channel = "G";
        REQUIRE(readHeightImage(path, options, &info).values == g);
        options.channel = "B";
        REQUIRE(readHeightImage(path, options, &info).values == b);
        CHECK(info.channel == "B");
    }
    SECTION("a channel that is not there: the message names those that are") {
        options.channel = "Z";
        const std::string message = fileErrorOf([&] { readHeightImage(path, options); });
        CHECK(message.find(path) != std::string::npos);
        CHECK(message.find("'Z'") != std::string::npos);
        CHECK(message.find("'B', 'G', 'R'") != std::string::npos);
    }
    SECTION("Y is taken before R; a lone channel whatever its name") {
        writeExr(dir.file("ry.exr"), windowOf(w, h), {{"R", r}, {"Y", b}});
        REQUIRE(readHeightImage(dir.file("ry.exr")).values == b);
        writeExr(dir.file("one.exr"), windowOf(w, h), {{"displacement.height", g}});
        REQUIRE(readHeightImage(dir.file("one.exr"), {}, &info).values == g);
        CHECK(info.channel == "displacement.height");
    }
    SECTION("several channels, neither Y nor R: the message asks for a choice") {
        writeExr(dir.file("gb.exr"), windowOf(w, h), {{"G", g}, {"B", b}});
        requireReadError(dir.file("gb.exr"), "none is 'Y' or 'R'");
    }
    SECTION("half and uint channels") {
        writeExr(dir.file("half.exr"), windowOf(w, h), {{"Y", r}}, Imf::HALF);
        REQUIRE(readHeightImage(dir.file("half.exr"), {}, &info).values == r); // quarters are exact halves
        CHECK(info.bits == 16);
        writeExr(dir.file("uint.exr"), windowOf(w, h), {{"Y", b}}, Imf::UINT);
        std::vector<float> truncated; // writeExr truncates to uint
        for (const float v : b) truncated.push_back(std::floor(v));
        REQUIRE(readHeightImage(dir.file("uint.exr"), {}, &info).values == truncated); // integers < 2^24: exact
        CHECK(!info.floatSamples);
        CHECK(!info.normalised);
    }
}

TEST_CASE("image files: EXR data windows, tiles and parts", "[image_files]") {
    TempDir dir;
    const HeightImage img = analytic(37, 21);
    SECTION("the data window, whatever its origin; the display window is ignored") {
        const Imath::Box2i data(Imath::V2i(-10, 5), Imath::V2i(-10 + 36, 5 + 20));
        Imf::Header header(Imath::Box2i(Imath::V2i(0, 0), Imath::V2i(99, 99)), data);
        header.channels().insert("Y", Imf::Channel(Imf::FLOAT));
        Imf::FrameBuffer frame;
        frame.insert("Y", Imf::Slice::Make(Imf::FLOAT, img.values.data(), data));
        {
            Imf::OutputFile file(dir.file("w.exr").c_str(), header);
            file.setFrameBuffer(frame);
            file.writePixels(21);
        }
        REQUIRE(readHeightImage(dir.file("w.exr")).values == img.values); // float: exact
    }
    SECTION("tiled and mip-mapped: level 0") {
        writeTiledExr(dir.file("t.exr"), img, 16);
        REQUIRE(readHeightImage(dir.file("t.exr")).values == img.values); // float: exact
    }
    SECTION("multi-part: the first part") {
        // Parts share their display window (OpenEXR requires it); their data windows differ.
        Imf::Header first(37, 21), second(first.displayWindow(), windowOf(8, 8));
        first.setName("heights");
        second.setName("other");
        for (Imf::Header* header : {&first, &second}) {
            header->setType(Imf::SCANLINEIMAGE);
            header->channels().insert("Y", Imf::Channel(Imf::FLOAT));
        }
        const HeightImage other = constant(8, 8, -3.0f);
        {
            const Imf::Header headers[] = {first, second};
            Imf::MultiPartOutputFile file(dir.file("m.exr").c_str(), headers, 2);
            for (int part = 0; part < 2; ++part) {
                Imf::OutputPart out(file, part);
                const HeightImage& source = part == 0 ? img : other;
                Imf::FrameBuffer frame;
                frame.insert("Y", Imf::Slice::Make(Imf::FLOAT, source.values.data(), headers[part].dataWindow()));
                out.setFrameBuffer(frame);
                out.writePixels(source.height);
            }
        }
        REQUIRE(readHeightImage(dir.file("m.exr")).values == img.values); // float: exact
    }
}

TEST_CASE("image files: TIFF layouts and channels", "[image_files]") {
    TempDir dir;
    const std::string path = dir.file("c.tif");
    const int w = 41, h = 23;
    // Distinct 16-bit samples per channel.
    const SampleFn rgba = [](int x, int y, int c) { return static_cast<double>((x * 1031 + y * 17 + c * 20011) % 65536); };
    const auto expected = [&](int c) {
        std::vector<float> v;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) v.push_back(static_cast<float>(rgba(x, y, c) / 65535.0));
        return v;
    };
    HeightReadOptions options;
    HeightImageInfo info;
    TiffSpec spec;
    spec.width = w;
    spec.height = h;
    spec.samples = 4;
    spec.bits = 16;
    spec.photometric = PHOTOMETRIC_RGB;
    spec.alpha = true;
    // Samples are read as v / 65535 rounded to float, as computed for `expected`: exact.
    for (const bool separate : {false, true})
        for (const int tile : {0, 16}) {
            DYNAMIC_SECTION("RGBA, " << (separate ? "separate planes" : "interleaved") << ", "
                                     << (tile ? "tiles" : "strips")) {
                spec.separate = separate;
                spec.tile = tile;
                writeTiff(path, spec, rgba);
                REQUIRE(readHeightImage(path, options, &info).values == expected(0)); // "": R
                CHECK(info.channels == 4);
                CHECK(info.channel == "0");
                options.channel = "G";
                REQUIRE(readHeightImage(path, options, &info).values == expected(1));
                CHECK(info.channel == "1");
                options.channel = "2";
                REQUIRE(readHeightImage(path, options).values == expected(2));
                options.channel = "A";
                REQUIRE(readHeightImage(path, options, &info).values == expected(3));
                CHECK(info.channel == "3");
                options.channel = "4";
                requireReadError(path, "0 (R)', '1 (G)', '2 (B)', '3 (A)'", options);
                options.channel = "Y";
                requireReadError(path, "has no channel 'Y'", options);
            }
        }
    SECTION("grey + alpha, 8-bit") {
        spec.samples = 2;
        spec.bits = 8;
        spec.photometric = PHOTOMETRIC_MINISBLACK;
        const SampleFn ga = [](int x, int y, int c) { return static_cast<double>((x * 3 + y * 5 + c * 100) % 256); };
        writeTiff(path, spec, ga);
        options.channel = "A";
        const HeightImage alpha = readHeightImage(path, options);
        REQUIRE(alpha.at(3, 2) == static_cast<float>(ga(3, 2, 1) / 255.0)); // v / 255 rounded to float
        options.channel = "Y";
        REQUIRE(readHeightImage(path, options).at(3, 2) == static_cast<float>(ga(3, 2, 0) / 255.0)); // as above
        options.channel = "R";
        requireReadError(path, "0 (grey)', '1 (A)'", options);
    }
    SECTION("palette: a component of the colour map") {
        spec.samples = 1;
        spec.bits = 8;
        spec.alpha = false;
        spec.photometric = PHOTOMETRIC_PALETTE;
        for (int c = 0; c < 3; ++c)
            for (int i = 0; i < 256; ++i) spec.colourMap.push_back(static_cast<std::uint16_t>(i * 257 - c * i));
        const SampleFn index = [](int x, int y, int) { return static_cast<double>((x + 2 * y) % 256); };
        writeTiff(path, spec, index);
        options.channel = "B";
        const HeightImage blue = readHeightImage(path, options, &info);
        const int i = static_cast<int>(index(5, 7, 0));
        REQUIRE(blue.at(5, 7) == static_cast<float>(i * 257 - 2 * i) / 65535.0f); // the reader's own expression
        CHECK(info.channels == 3);
    }
    SECTION("BigTIFF") {
        spec.bigTiff = true;
        writeTiff(path, spec, rgba);
        REQUIRE(readBytes(path)[2] == 43); // "II+\0"
        options.channel = "B";
        REQUIRE(readHeightImage(path, options).values == expected(2)); // exact, as above
    }
    SECTION("big-endian 16-bit, hand-built") {
        const std::vector<std::uint16_t> raw = {0, 1000, 65535, 258, 4660, 30000};
        std::vector<unsigned char> data;
        for (const std::uint16_t v : raw) {
            data.push_back(static_cast<unsigned char>(v >> 8));
            data.push_back(static_cast<unsigned char>(v & 0xFF));
        }
        writeBytes(path, handBuiltTiff(true, greyIfd(3, 2, 16, 12), data));
        const HeightImage img = readHeightImage(path);
        REQUIRE(img.width == 3);
        REQUIRE(img.height == 2);
        for (std::size_t k = 0; k < raw.size(); ++k)
            REQUIRE(img.values[k] == static_cast<float>(raw[k] / 65535.0)); // v / 65535 rounded to float
    }
    SECTION("unsupported kinds are named") {
        spec.samples = 1;
        spec.alpha = false;
        spec.photometric = PHOTOMETRIC_MINISBLACK;
        const SampleFn one = [](int, int, int) { return 1.0; };
        spec.format = SAMPLEFORMAT_INT;
        writeTiff(path, spec, one);
        requireReadError(path, "signed integer samples are not supported");
        spec.format = SAMPLEFORMAT_UINT;
        spec.orientation = ORIENTATION_BOTRIGHT;
        writeTiff(path, spec, one);
        requireReadError(path, "orientation 3 is not supported");
        spec.orientation = ORIENTATION_TOPLEFT;
        spec.photometric = PHOTOMETRIC_MINISWHITE;
        writeTiff(path, spec, one);
        requireReadError(path, "(min-is-white) is not supported");
        writeBytes(path, handBuiltTiff(false, greyIfd(8, 1, 1, 1), {0x5A}));
        requireReadError(path, "1-bit integer samples are not supported");
    }
}

TEST_CASE("image files: sizes are checked before anything is allocated", "[image_files]") {
    TempDir dir;
    SECTION("a TIFF header claiming 1e6 x 1e6") {
        const std::string path = dir.file("huge.tif");
        writeBytes(path, handBuiltTiff(false, greyIfd(1000000, 1000000, 8, 16), std::vector<unsigned char>(16, 7)));
        requireReadError(path, "too large (1000000 x 1000000; at most 16384 per side)");
    }
    SECTION("an EXR whose data window is huge, or overflows 32 bits") {
        const std::string path = dir.file("huge.exr");
        dispmap::writeHeightExr(path, constant(4, 4, 1.0f));
        std::vector<unsigned char> bytes = readBytes(path);
        patchDataWindow(bytes, 0, 0, 999999, 3);
        writeBytes(path, bytes);
        requireReadError(path, "too large (1000000 x 4");
        const std::int32_t lo = std::numeric_limits<std::int32_t>::min(), hi = std::numeric_limits<std::int32_t>::max();
        patchDataWindow(bytes, lo, lo, hi, hi);
        writeBytes(path, bytes);
        requireReadError(path, "too large (4294967296 x 4294967296");
        patchDataWindow(bytes, 5, 0, 2, 3);
        writeBytes(path, bytes);
        requireReadError(path, "empty or inverted data window");
    }
    SECTION("the caller's maxSide, for each format") {
        HeightReadOptions options;
        options.maxSide = 100;
        const HeightImage wide = constant(101, 3, 0.5f);
        dispmap::writeHeightExr(dir.file("w.exr"), wide);
        dispmap::writeHeightTiff(dir.file("w.tif"), wide, 16, false);
        dispmap::writeHeightPng16(dir.file("w.png"), wide);
        for (const char* name : {"w.exr", "w.tif", "w.png"}) requireReadError(dir.file(name), "too large", options);
        options.maxSide = 101;
        for (const char* name : {"w.exr", "w.tif", "w.png"}) REQUIRE(readHeightImage(dir.file(name), options).width == 101);
    }
    SECTION("an EXR attribute claiming more bytes than the file has") {
        const std::string path = dir.file("attr.exr");
        dispmap::writeHeightExr(path, constant(4, 4, 1.0f));
        std::vector<unsigned char> bytes = readBytes(path);
        static const char key[] = "compression\0compression"; // size follows
        const auto it = std::search(bytes.begin(), bytes.end(), key, key + sizeof key);
        REQUIRE(it != bytes.end());
        const auto at = static_cast<std::size_t>(it - bytes.begin()) + sizeof key;
        bytes[at + 3] = 0x7F; // 2 GiB and more
        writeBytes(path, bytes);
        requireReadError(path, "attribute 'compression' claims");
    }
    SECTION("an EXR whose tiles would need a larger offset table than the file") {
        const std::string path = dir.file("tiles.exr");
        writeTiledExr(path, constant(4000, 3, 0.5f), 16);
        std::vector<unsigned char> bytes = readBytes(path);
        static const char key[] = "tiles\0tiledesc"; // size (4 bytes), then x and y size
        const auto it = std::search(bytes.begin(), bytes.end(), key, key + sizeof key);
        REQUIRE(it != bytes.end());
        const auto at = static_cast<std::size_t>(it - bytes.begin()) + sizeof key + 4;
        bytes[at] = 1; // 1 x 1 tiles: 12000 of them, 96000 bytes of offsets
        bytes[at + 4] = 1;
        writeBytes(path, bytes);
        requireReadError(path, "12000 tiles of 1 x 1 need a larger offset table than the file holds");
    }
    SECTION("a deep EXR is refused") {
        const std::string path = dir.file("deep.exr");
        dispmap::writeHeightExr(path, constant(4, 4, 1.0f));
        std::vector<unsigned char> bytes = readBytes(path);
        bytes[5] |= 0x08; // the non-image (deep) flag, 0x800
        writeBytes(path, bytes);
        requireReadError(path, "a deep image");
    }
}

TEST_CASE("image files: damaged and unknown files", "[image_files]") {
    TempDir dir;
    const HeightImage img = analytic(257, 129);
    // EXR (ZIP: zlib checks each block) and PNG (CRC per chunk) detect any damage to their
    // data; TIFF has no checksum, but libtiff reports the broken Deflate stream of this 8-bit
    // file (a float file damaged the same way happens to decode to a NaN, also refused).
    dispmap::writeHeightExr(dir.file("h.exr"), img);
    dispmap::writeHeightTiff(dir.file("h.tif"), img, 8, false);
    dispmap::writeHeightPng16(dir.file("h.png"), img);
    for (const char* name : {"h.exr", "h.tif", "h.png"}) {
        const std::string path = dir.file(name);
        const std::vector<unsigned char> bytes = readBytes(path);
        DYNAMIC_SECTION(name << ": the first half") {
            writeBytes(path, std::vector<unsigned char>(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(bytes.size() / 2)));
            // libtiff writes the directory last: a TIFF's first half has none.
            requireReadError(path, name[2] == 't' ? "libtiff cannot read it" : "truncated");
        }
        DYNAMIC_SECTION(name << ": bytes overwritten in the middle") {
            std::vector<unsigned char> damaged = bytes;
            for (std::size_t i = damaged.size() / 2; i < damaged.size() / 2 + 64; ++i) damaged[i] = 0xFF;
            writeBytes(path, damaged);
            requireReadError(path, name[2] == 'e' ? "OpenEXR" : name[2] == 't' ? "cannot read row" : "");
        }
    }
    SECTION("other formats, and no bytes at all") {
        writeBytes(dir.file("x.exr"), {'<', '?', 'x', 'm', 'l', ' '});
        requireReadError(dir.file("x.exr"), "is not a PNG, EXR or TIFF file (it starts with bytes 3c 3f 78 6d)");
        writeBytes(dir.file("jpeg.tif"), {0xFF, 0xD8, 0xFF, 0xE0, 0, 0x10});
        requireReadError(dir.file("jpeg.tif"), "is not a PNG, EXR or TIFF file");
        writeBytes(dir.file("empty.png"), {});
        requireReadError(dir.file("empty.png"), "is empty");
        requireReadError(dir.file("missing.exr"), "cannot open");
        requireReadError(dir.path.string(), "not a regular file");
    }
}

TEST_CASE("image files: non-finite float samples name the pixel and channel", "[image_files]") {
    TempDir dir;
    const int w = 11, h = 6;
    std::vector<float> values(static_cast<std::size_t>(w * h), 0.25f);
    SECTION("EXR float NaN") {
        values[3 * w + 5] = std::numeric_limits<float>::quiet_NaN();
        writeExr(dir.file("nan.exr"), windowOf(w, h), {{"height", values}});
        requireReadError(dir.file("nan.exr"), "pixel (5, 3) of channel 'height' is not finite (nan)");
    }
    SECTION("EXR half infinity") {
        values[w + 2] = std::numeric_limits<float>::infinity();
        writeExr(dir.file("inf.exr"), windowOf(w, h), {{"Y", values}}, Imf::HALF);
        requireReadError(dir.file("inf.exr"), "pixel (2, 1) of channel 'Y' is not finite (+inf)");
    }
    SECTION("TIFF float NaN") {
        TiffSpec spec;
        spec.width = w;
        spec.height = h;
        spec.bits = 32;
        spec.format = SAMPLEFORMAT_IEEEFP;
        writeTiff(dir.file("nan.tif"), spec, [](int x, int y, int) {
            return x == 7 && y == 4 ? std::numeric_limits<double>::quiet_NaN() : 0.5;
        });
        requireReadError(dir.file("nan.tif"), "pixel (7, 4) of channel '0' is not finite (nan)");
    }
}

TEST_CASE("image files: writers refuse what they cannot store", "[image_files]") {
    TempDir dir;
    const std::string path = dir.file("out.tif");
    HeightImage img = constant(4, 3, 0.5f);
    REQUIRE_THROWS_AS(dispmap::writeHeightTiff(path, img, 12, false), ArgumentError);
    REQUIRE_THROWS_AS(dispmap::writeHeightTiff(path, img, 8, true), ArgumentError);
    img.values[5] = 1.5f;
    REQUIRE_THROWS_AS(dispmap::writeHeightTiff(path, img, 16, false), ArgumentError); // integers hold [0, 1]
    dispmap::writeHeightTiff(path, img, 32, true);                                   // floats hold anything finite
    REQUIRE(readHeightImage(path).values == img.values);                              // exact: float
    img.values[5] = 70000.0f;
    REQUIRE_THROWS_AS(dispmap::writeHeightTiff(dir.file("half.tif"), img, 16, true), ArgumentError);
    REQUIRE_THROWS_AS(dispmap::writeHeightExr(dir.file("half.exr"), img, true), ArgumentError);
    img.values[5] = std::numeric_limits<float>::quiet_NaN();
    REQUIRE_THROWS_AS(dispmap::writeHeightExr(dir.file("nan.exr"), img), ArgumentError);
    img.values.pop_back();
    REQUIRE_THROWS_AS(dispmap::writeHeightExr(dir.file("short.exr"), img), ArgumentError);
    REQUIRE(dir.entries() == std::set<std::string>{"out.tif"}); // nothing else written, no temporaries
}

TEST_CASE("image files: UDIM sets", "[image_files]") {
    TempDir dir;
    CHECK(dispmap::isUdimPattern("a/h.<UDIM>.exr"));
    CHECK(dispmap::isUdimPattern("h_<udim>.tif"));
    CHECK(dispmap::isUdimPattern("h.%(UDIM)d.png"));
    CHECK(!dispmap::isUdimPattern("h.1001.exr"));
    CHECK(!dispmap::isUdimPattern("h.<Udim>.exr"));
    CHECK(dispmap::udimOf(0, 0) == 1001);
    CHECK(dispmap::udimOf(9, 0) == 1010);
    CHECK(dispmap::udimOf(1, 1) == 1012);
    CHECK(dispmap::udimOf(9, 9) == 1100);
    CHECK_THROWS_AS(dispmap::udimOf(10, 0), ArgumentError);
    CHECK(dispmap::udimPath("a/h.<UDIM>.exr", 1011) == "a/h.1011.exr");
    CHECK_THROWS_AS(dispmap::udimPath("a/h.exr", 1011), ArgumentError);

    // Tile k has its own size and values k + x / 8 + y / 64 (exact in float).
    const std::map<int, std::pair<int, int>> sizes = {{1001, {16, 8}}, {1002, {8, 8}}, {1011, {4, 2}}};
    const auto tileImage = [](int udim, int width, int height) {
        HeightImage t = constant(width, height, 0.0f);
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x)
                t.values[static_cast<std::size_t>(y * width + x)] = static_cast<float>(udim) + static_cast<float>(x) / 8.0f +
                                                                    static_cast<float>(y) / 64.0f;
        return t;
    };
    for (const auto& [udim, size] : sizes)
        dispmap::writeHeightExr(dir.file("h." + std::to_string(udim) + ".exr"), tileImage(udim, size.first, size.second));
    // Names that are not tiles of the set: never read (their content would fail).
    for (const char* other : {"h.1000.exr", "h.1101.exr", "h.10011.exr", "h.10a1.exr", "h.1003.exr.bak", "g.1004.exr"})
        writeBytes(dir.file(other), {'n', 'o'});

    for (const char* token : {"<UDIM>", "<udim>", "%(UDIM)d"}) {
        DYNAMIC_SECTION("pattern with " << token) {
            const std::string pattern = dir.file(std::string("h.") + token + ".exr");
            const dispmap::UdimImages set = dispmap::readUdimImages(pattern);
            CHECK(set.pattern == pattern);
            REQUIRE(set.tiles.size() == 3);
            for (const auto& [udim, size] : sizes) {
                REQUIRE(set.tiles.count(udim) == 1);
                REQUIRE(set.tiles.at(udim)->values == tileImage(udim, size.first, size.second).values); // float: exact
            }
        }
    }
    SECTION("a tile that cannot be read fails the set, naming the tile") {
        writeBytes(dir.file("h.1003.exr"), {'n', 'o'});
        requireReadError(dir.file("h.1003.exr"), "not a PNG, EXR or TIFF");
        const std::string message = fileErrorOf([&] { dispmap::readUdimImages(dir.file("h.<UDIM>.exr")); });
        CHECK(message.find("h.1003.exr") != std::string::npos);
    }
    SECTION("no file of the set") {
        const std::string pattern = dir.file("x.<UDIM>.exr");
        const std::string message = fileErrorOf([&] { dispmap::readUdimImages(pattern); });
        CHECK(message.find(pattern) != std::string::npos);
        CHECK(message.find("folder '" + dir.path.string() + "'") != std::string::npos);
        CHECK(message.find("holds no file") != std::string::npos);
    }
    SECTION("a folder that does not exist, or is a file") {
        const std::string pattern = dir.file("nope/h.<UDIM>.exr");
        const std::string message = fileErrorOf([&] { dispmap::readUdimImages(pattern); });
        CHECK(message.find(pattern) != std::string::npos);
        CHECK(message.find("does not exist") != std::string::npos);
        const std::string notFolder = dir.file("h.1001.exr/h.<UDIM>.exr");
        CHECK(fileErrorOf([&] { dispmap::readUdimImages(notFolder); }).find("is not a folder") != std::string::npos);
    }
    SECTION("a pattern without exactly one token in its file name") {
        CHECK_THROWS_AS(dispmap::readUdimImages(dir.file("h.exr")), ArgumentError);
        CHECK_THROWS_AS(dispmap::readUdimImages(dir.file("h.<UDIM>.<udim>.exr")), ArgumentError);
        CHECK_THROWS_AS(dispmap::readUdimImages(dir.file("<UDIM>/h.exr")), ArgumentError);
    }
}

} // namespace dmtest_test_image_files
