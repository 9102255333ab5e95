#pragma once
// Whole-file reads and atomic writes (temporary file + rename) shared by the file formats.
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <system_error>
#include <vector>

#include "dispmap/core/error.h"

namespace dispmap::detail {
// Owns a C FILE*; closes it (ignoring errors) when dropped. Writers close explicitly.
struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

// The whole content of a file. Throws FileError "cannot open/read <what> '<path>': reason".
inline std::vector<unsigned char> readFileBytes(const std::string& path, const char* what) {
    FilePtr f(std::fopen(path.c_str(), "rb"));
    if (!f) throw FileError(std::string("cannot open ") + what + " '" + path + "': " + std::strerror(errno));
    std::vector<unsigned char> bytes;
    unsigned char chunk[16384];
    for (;;) {
        const std::size_t n = std::fread(chunk, 1, sizeof chunk, f.get());
        bytes.insert(bytes.end(), chunk, chunk + n);
        if (n < sizeof chunk) break;
    }
    if (std::ferror(f.get()))
        throw FileError(std::string("cannot read ") + what + " '" + path + "': " + std::strerror(errno));
    return bytes;
}

// Replaces (or creates) the file at path with bytes, atomically: the bytes go to a new
// temporary file next to it, which is then renamed over path. On failure the temporary is
// removed, an existing file is left as it was, and FileError names path and the reason.
inline void writeFileAtomically(const std::string& path, const std::vector<unsigned char>& bytes,
                                const char* what) {
    const auto fail = [&](const std::string& why) {
        return FileError(std::string("cannot write ") + what + " '" + path + "': " + why);
    };
    static std::atomic<unsigned long long> counter{0};
    std::mt19937_64 rng(std::random_device{}() ^ (counter.fetch_add(1) * 0x9E3779B97F4A7C15ull));
    std::string tmp;
    FilePtr f;
    for (int attempt = 0; attempt < 16 && !f; ++attempt) {
        tmp = path + ".tmp-" + std::to_string(rng());
        f.reset(std::fopen(tmp.c_str(), "wbx")); // "x": fail rather than reuse an existing name
        if (!f && errno != EEXIST) break;
    }
    if (!f) throw fail("cannot create temporary file '" + tmp + "': " + std::strerror(errno));

    const bool written =
        std::fwrite(bytes.data(), 1, bytes.size(), f.get()) == bytes.size() && std::fflush(f.get()) == 0;
    const int writeErrno = errno;
    const bool closed = std::fclose(f.release()) == 0;
    const int closeErrno = errno;
    if (!written || !closed) {
        std::remove(tmp.c_str());
        throw fail(std::strerror(!written ? writeErrno : closeErrno));
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) {
        std::remove(tmp.c_str());
        throw fail("cannot rename the temporary file over it: " + ec.message());
    }
}
} // namespace dispmap::detail
