// Height images (height_image.h): exact 16-bit round trips, 8-bit and converted files,
// bilinear sampling conventions, and rejected inputs without partial files left behind.
#include <catch2/catch.hpp>

#include "test_files.h"

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <png.h>

#include "dispmap/io/png.h"

// Everything of this file in its own namespace: the tests build as a unity build
// (tests/CMakeLists.txt), where each file's helpers must not meet another's.
namespace dmtest_height_image {

namespace fs = std::filesystem;
using dispmap::ArgumentError;
using dispmap::FileError;
using dispmap::HeightImage;

using dmtest::readBytes;
using dmtest::writeBytes;
struct TempDir : dmtest::TempDir {
    TempDir() : dmtest::TempDir("dispmap_height_image_test_") {}
};

namespace {


// Writes a PNG with libpng's simplified API (independent of the code under test): format is
// a PNG_FORMAT_* value, pixels top row first, 8-bit samples or, with PNG_FORMAT_FLAG_LINEAR,
// 16-bit ones in host order; with PNG_FORMAT_FLAG_COLORMAP, pixels are indices into the
// grey palette.
void writeReferencePng(const std::string& path, int width, int height, png_uint_32 format, const void* pixels,
                       const std::vector<unsigned char>& palette = {}) {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    image.width = static_cast<png_uint_32>(width);
    image.height = static_cast<png_uint_32>(height);
    image.format = format;
    image.colormap_entries = static_cast<png_uint_32>(palette.size());
    REQUIRE(png_image_write_to_file(&image, path.c_str(), 0, pixels, 0,
                                    palette.empty() ? nullptr : palette.data()) != 0);
}

HeightImage makeImage(int width, int height, std::vector<float> values) {
    HeightImage img;
    img.width = width;
    img.height = height;
    img.values = std::move(values);
    return img;
}

// A 4 x 3 image with distinct values, value (x, y) = (1 + x + 4 y) / 16.
HeightImage ramp() {
    std::vector<float> v(12);
    for (std::size_t i = 0; i < v.size(); ++i)
        v[i] = static_cast<float>(i + 1) / 16.0f;
    return makeImage(4, 3, v);
}

double at(const HeightImage& img, int x, int y) {
    return static_cast<double>(img.at(x, y));
}

} // namespace

TEST_CASE("height image: 16-bit round trip is exact", "[height_image]") {
    TempDir dir;
    const std::string path = dir.file("h.png");
    SECTION("a small odd-sized image") {
        std::vector<float> v(7 * 5);
        for (std::size_t i = 0; i < v.size(); ++i)
            v[i] = static_cast<float>((i * 7919) % 65536) / 65535.0f;
        v.front() = 0.0f;
        v.back() = 1.0f;
        const HeightImage img = makeImage(7, 5, v);
        dispmap::writeHeightPng16(path, img);
        const HeightImage back = dispmap::readHeightPng(path);
        REQUIRE(back.width == 7);
        REQUIRE(back.height == 5);
        REQUIRE(back.values == img.values);
        const std::vector<unsigned char> b = readBytes(path);
        REQUIRE(b[24] == 16); // IHDR bit depth
        REQUIRE(b[25] == 0);  // IHDR colour type: grey
    }
    SECTION("every 16-bit code, k / 65535") {
        std::vector<float> v(256 * 256);
        for (std::size_t i = 0; i < v.size(); ++i)
            v[i] = static_cast<float>(i) / 65535.0f;
        dispmap::writeHeightPng16(path, makeImage(256, 256, v));
        REQUIRE(dispmap::readHeightPng(path).values == v);
    }
    SECTION("a 16-bit file from another writer") {
        std::vector<png_uint_16> raw = {0, 1, 300, 65534, 65535, 40000};
        writeReferencePng(path, 3, 2, PNG_FORMAT_LINEAR_Y, raw.data());
        const HeightImage back = dispmap::readHeightPng(path);
        REQUIRE(back.width == 3);
        REQUIRE(back.height == 2);
        for (std::size_t i = 0; i < raw.size(); ++i)
            REQUIRE(back.values[i] == static_cast<float>(raw[i]) / 65535.0f);
    }
    REQUIRE(dir.entries() == std::set<std::string>{"h.png"}); // no temporaries left
}

TEST_CASE("height image: 8-bit and converted files", "[height_image]") {
    TempDir dir;
    const std::string path = dir.file("h8.png");
    SECTION("8-bit grey, row 0 = top row of the file") {
        const std::vector<unsigned char> raw = {0, 51, 255, 128, 1, 254};
        writeReferencePng(path, 3, 2, PNG_FORMAT_GRAY, raw.data());
        const HeightImage img = dispmap::readHeightPng(path);
        REQUIRE(img.width == 3);
        REQUIRE(img.height == 2);
        for (int y = 0; y < 2; ++y)
            for (int x = 0; x < 3; ++x)
                REQUIRE(img.at(x, y) ==
                        static_cast<float>(raw[static_cast<std::size_t>(3 * y + x)]) / 255.0f);
    }
    SECTION("grey + alpha: alpha is dropped") {
        const std::vector<unsigned char> raw = {10, 255, 20, 0, 30, 128, 40, 7};
        writeReferencePng(path, 2, 2, PNG_FORMAT_GA, raw.data());
        const HeightImage img = dispmap::readHeightPng(path);
        REQUIRE(img.values == std::vector<float>{10 / 255.0f, 20 / 255.0f, 30 / 255.0f, 40 / 255.0f});
    }
    SECTION("RGB(A) with grey pixels reads exactly; a coloured pixel is rejected") {
        std::vector<unsigned char> rgb, rgba;
        std::vector<png_uint_16> rgb16;
        std::vector<float> expected8, expected16;
        for (unsigned v = 0; v < 256; ++v) {
            const auto b = static_cast<unsigned char>(v);
            rgb.insert(rgb.end(), {b, b, b});
            rgba.insert(rgba.end(), {b, b, b, static_cast<unsigned char>(255 - v)});
            const auto v16 = static_cast<png_uint_16>(v * 257 + (v % 7));
            rgb16.insert(rgb16.end(), {v16, v16, v16});
            expected8.push_back(static_cast<float>(v) / 255.0f);
            expected16.push_back(static_cast<float>(v16) / 65535.0f);
        }
        writeReferencePng(path, 16, 16, PNG_FORMAT_RGB, rgb.data()); // with an sRGB chunk
        REQUIRE(dispmap::readHeightPng(path).values == expected8);
        writeReferencePng(path, 16, 16, PNG_FORMAT_RGBA, rgba.data());
        REQUIRE(dispmap::readHeightPng(path).values == expected8);
        writeReferencePng(path, 16, 16, PNG_FORMAT_LINEAR_RGB, rgb16.data()); // 16-bit, gAMA 1.0
        REQUIRE(dispmap::readHeightPng(path).values == expected16);

        rgb[3 * 37 + 1] = static_cast<unsigned char>(rgb[3 * 37 + 1] ^ 1); // pixel (5, 2): G != R
        writeReferencePng(path, 16, 16, PNG_FORMAT_RGB, rgb.data());
        REQUIRE_THROWS_AS(dispmap::readHeightPng(path), FileError);
        REQUIRE_THROWS_WITH(dispmap::readHeightPng(path), Catch::Contains("pixel (5, 2) is coloured"));
    }
    SECTION("palette with grey entries") {
        const std::vector<unsigned char> indices = {0, 3, 1, 1, 2, 0};
        writeReferencePng(path, 3, 2, PNG_FORMAT_GRAY | PNG_FORMAT_FLAG_COLORMAP, indices.data(),
                          {0, 17, 200, 255});
        REQUIRE(readBytes(path)[25] == 3); // IHDR colour type: palette
        REQUIRE(dispmap::readHeightPng(path).values ==
                std::vector<float>{0.0f, 1.0f, 17 / 255.0f, 17 / 255.0f, 200 / 255.0f, 0.0f});
    }
}

TEST_CASE("height image: bilinear sampling conventions", "[height_image]") {
    const HeightImage img = ramp();
    const int w = img.width, h = img.height;
    const auto s = [w](double x) { return (x + 0.5) / w; };       // texel column -> s
    const auto t = [h](double y) { return 1.0 - (y + 0.5) / h; }; // texel row -> t
    for (bool wrap : {false, true}) {
        INFO("wrap = " << wrap);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                REQUIRE(dispmap::sampleHeightBilinear(img, s(x), t(y), wrap) ==
                        Approx(at(img, x, y)).margin(1e-12));
        // Half-way between two centres along s, along t, and between four.
        REQUIRE(dispmap::sampleHeightBilinear(img, s(1.5), t(2), wrap) ==
                Approx((at(img, 1, 2) + at(img, 2, 2)) / 2).margin(1e-12));
        REQUIRE(dispmap::sampleHeightBilinear(img, s(3), t(0.5), wrap) ==
                Approx((at(img, 3, 0) + at(img, 3, 1)) / 2).margin(1e-12));
        REQUIRE(dispmap::sampleHeightBilinear(img, s(0.5), t(1.5), wrap) ==
                Approx((at(img, 0, 1) + at(img, 1, 1) + at(img, 0, 2) + at(img, 1, 2)) / 4).margin(1e-12));
        // A quarter of the way: weights 3/4 and 1/4.
        REQUIRE(dispmap::sampleHeightBilinear(img, s(2.25), t(1), wrap) ==
                Approx(0.75 * at(img, 2, 1) + 0.25 * at(img, 3, 1)).margin(1e-12));
    }
    SECTION("t = 0 is the bottom row, t = 1 the top row") {
        REQUIRE(dispmap::sampleHeightBilinear(img, s(1), 0.0, false) ==
                Approx(at(img, 1, h - 1)).margin(1e-12));
        REQUIRE(dispmap::sampleHeightBilinear(img, s(1), 1.0, false) == Approx(at(img, 1, 0)).margin(1e-12));
        REQUIRE(dispmap::sampleHeightBilinear(img, s(1), t(h - 1), true) ==
                Approx(at(img, 1, h - 1)).margin(1e-12));
    }
    SECTION("clamp: outside the outer centres the edge texels") {
        REQUIRE(dispmap::sampleHeightBilinear(img, 0.0, t(1), false) == Approx(at(img, 0, 1)).margin(1e-12));
        REQUIRE(dispmap::sampleHeightBilinear(img, 1.0, t(1), false) ==
                Approx(at(img, w - 1, 1)).margin(1e-12));
        REQUIRE(dispmap::sampleHeightBilinear(img, -3.0, 7.0, false) == Approx(at(img, 0, 0)).margin(1e-12));
        REQUIRE(dispmap::sampleHeightBilinear(img, 5.0, -2.0, false) ==
                Approx(at(img, w - 1, h - 1)).margin(1e-12));
    }
    SECTION("wrap: the image repeats with period 1") {
        REQUIRE(dispmap::sampleHeightBilinear(img, 0.0, t(1), true) ==
                Approx((at(img, 0, 1) + at(img, w - 1, 1)) / 2).margin(1e-12));
        REQUIRE(dispmap::sampleHeightBilinear(img, s(1), 0.0, true) ==
                Approx((at(img, 1, h - 1) + at(img, 1, 0)) / 2).margin(1e-12));
        for (double shift : {-2.0, -1.0, 1.0, 3.0})
            REQUIRE(dispmap::sampleHeightBilinear(img, 0.3 + shift, 0.7 - shift, true) ==
                    Approx(dispmap::sampleHeightBilinear(img, 0.3, 0.7, true)).margin(1e-9));
    }
    SECTION("invalid arguments") {
        REQUIRE_THROWS_AS(dispmap::sampleHeightBilinear(img, std::nan(""), 0.5, false), ArgumentError);
        REQUIRE_THROWS_AS(dispmap::sampleHeightBilinear(img, 0.5, HUGE_VAL, true), ArgumentError);
        REQUIRE_THROWS_WITH(dispmap::sampleHeightBilinear(HeightImage{}, 0.5, 0.5, false),
                            Catch::Contains("empty"));
    }
}

TEST_CASE("height image: bad files are rejected with a reason", "[height_image]") {
    TempDir dir;
    std::vector<float> noise(64 * 64);
    std::mt19937 rng(1);
    for (float& v : noise)
        v = static_cast<float>(rng() % 65536) / 65535.0f;
    const std::string goodPath = dir.file("good.png");
    dispmap::writeHeightPng16(goodPath, makeImage(64, 64, noise));
    const std::vector<unsigned char> good = readBytes(goodPath);
    const std::string path = dir.file("bad.png");
    const auto readEdited = [&](const auto& edit) {
        std::vector<unsigned char> b = good;
        edit(b);
        writeBytes(path, b);
        return dispmap::readHeightPng(path);
    };

    const std::string missing = dir.file("missing.png");
    REQUIRE_THROWS_AS(dispmap::readHeightPng(missing), FileError);
    REQUIRE_THROWS_WITH(dispmap::readHeightPng(missing),
                        Catch::Contains("cannot open") && Catch::Contains(missing));

    writeBytes(path, {'h', 'e', 'l', 'l', 'o', '\n'});
    REQUIRE_THROWS_AS(dispmap::readHeightPng(path), FileError);
    REQUIRE_THROWS_WITH(dispmap::readHeightPng(path), Catch::Contains("not a PNG") && Catch::Contains(path));
    writeBytes(path, {});
    REQUIRE_THROWS_WITH(dispmap::readHeightPng(path), Catch::Contains("not a PNG"));

    const auto firstHalf = [](auto& b) { b.resize(b.size() / 2); };
    REQUIRE_THROWS_AS(readEdited(firstHalf), FileError);
    REQUIRE_THROWS_WITH(readEdited(firstHalf), Catch::Contains("truncated"));
    const auto noIend = [](auto& b) { b.resize(b.size() - 12); };
    REQUIRE_THROWS_WITH(readEdited(noIend), Catch::Contains("truncated"));

    const auto setWidth = [](std::uint32_t width) {
        return [width](auto& b) {
            for (std::size_t i = 0; i < 4; ++i)
                b[16 + i] = static_cast<unsigned char>(width >> (8 * (3 - i)));
        };
    };
    REQUIRE_THROWS_AS(readEdited(setWidth(0)), FileError);
    REQUIRE_THROWS_WITH(readEdited(setWidth(0)), Catch::Contains("zero size"));
    REQUIRE_THROWS_AS(readEdited(setWidth(16385)), FileError);
    REQUIRE_THROWS_WITH(readEdited(setWidth(16385)), Catch::Contains("too large"));

    // A damaged byte inside the image data: libpng's chunk CRC catches it.
    REQUIRE_THROWS_AS(readEdited([](auto& b) { b[b.size() / 2] ^= 0x10; }), FileError);

    SECTION("every prefix of a small file") {
        const std::vector<unsigned char> raw = {0, 51, 255, 128, 1, 254};
        writeReferencePng(goodPath, 3, 2, PNG_FORMAT_GRAY, raw.data());
        const std::vector<unsigned char> small = readBytes(goodPath);
        for (std::size_t n = 0; n < small.size(); ++n) {
            INFO("prefix of " << n << " of " << small.size() << " bytes");
            writeBytes(path, std::vector<unsigned char>(small.begin(),
                                                        small.begin() + static_cast<std::ptrdiff_t>(n)));
            REQUIRE_THROWS_AS(dispmap::readHeightPng(path), FileError);
        }
    }
}

TEST_CASE("height image: invalid images are not written, nothing half-written", "[height_image]") {
    TempDir dir;
    const std::string path = dir.file("h.png");
    dispmap::writeHeightPng16(path, ramp());
    const std::vector<unsigned char> before = readBytes(path);

    const auto withValue = [](int x, int y, float v) {
        HeightImage img = ramp();
        img.values[static_cast<std::size_t>(y * img.width + x)] = v;
        return img;
    };
    REQUIRE_THROWS_AS(dispmap::writeHeightPng16(path, withValue(1, 0, std::nanf(""))), ArgumentError);
    REQUIRE_THROWS_WITH(dispmap::writeHeightPng16(path, withValue(1, 0, std::nanf(""))),
                        Catch::Contains("texel (1, 0)") && Catch::Contains("nan"));
    REQUIRE_THROWS_AS(dispmap::writeHeightPng16(path, withValue(0, 2, 1.5f)), ArgumentError);
    REQUIRE_THROWS_WITH(dispmap::writeHeightPng16(path, withValue(0, 2, 1.5f)),
                        Catch::Contains("texel (0, 2) has value 1.5"));
    REQUIRE_THROWS_WITH(dispmap::writeHeightPng16(path, withValue(3, 1, -0.25f)),
                        Catch::Contains("texel (3, 1) has value -0.25"));
    REQUIRE_THROWS_WITH(
        dispmap::writeHeightPng16(path, withValue(2, 2, std::numeric_limits<float>::infinity())),
        Catch::Contains("texel (2, 2)"));
    REQUIRE_THROWS_AS(dispmap::writeHeightPng16(path, makeImage(0, 3, {})), ArgumentError);
    REQUIRE_THROWS_WITH(dispmap::writeHeightPng16(path, makeImage(0, 3, {})), Catch::Contains("size 0 x 3"));
    REQUIRE_THROWS_WITH(dispmap::writeHeightPng16(path, makeImage(16385, 1, std::vector<float>(16385, 0.5f))),
                        Catch::Contains("size 16385 x 1"));
    REQUIRE_THROWS_WITH(dispmap::writeHeightPng16(path, makeImage(2, 2, {0.5f, 0.5f, 0.5f})),
                        Catch::Contains("3 values for a 2 x 2 image"));
    REQUIRE(readBytes(path) == before);

    SECTION("into a directory that does not exist") {
        const std::string target = (dir.path / "no_such_dir" / "h.png").string();
        REQUIRE_THROWS_AS(dispmap::writeHeightPng16(target, ramp()), FileError);
        REQUIRE_THROWS_WITH(dispmap::writeHeightPng16(target, ramp()), Catch::Contains("no_such_dir"));
        REQUIRE(readBytes(path) == before);
    }
    SECTION("over an existing non-empty directory (the final rename fails)") {
        fs::create_directory(dir.file("occupied"));
        writeBytes(dir.file("occupied/keep.txt"), {'k'});
        REQUIRE_THROWS_AS(dispmap::writeHeightPng16(dir.file("occupied"), ramp()), FileError);
        REQUIRE(readBytes(dir.file("occupied/keep.txt")) == std::vector<unsigned char>{'k'});
        REQUIRE(dir.entries() == std::set<std::string>{"h.png", "occupied"}); // temporary removed
        fs::remove_all(dir.file("occupied"));
    }
    SECTION("a valid write replaces the old file") {
        std::vector<float> v(12, 16384 / 65535.0f);
        dispmap::writeHeightPng16(path, makeImage(4, 3, v));
        REQUIRE(dispmap::readHeightPng(path).values == v);
    }
    REQUIRE(dir.entries() == std::set<std::string>{"h.png"}); // no temporaries
}

} // namespace dmtest_height_image
