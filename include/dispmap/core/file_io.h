#pragma once
// Whole-file reads and atomic writes (temporary file + rename) shared by the file formats.
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "dispmap/core/error.h"

namespace dispmap::detail {
// Owns a C FILE*; closes it (ignoring errors) when dropped. Writers close explicitly.
struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

/// Largest file readFileBytes reads unless its caller gives a limit of its own: far above the
/// inputs dispmap is made for (a control mesh of a million faces is ~60 MB of OBJ), low enough
/// that a mistaken path (a disk image, a video) fails before it fills the memory.
inline constexpr std::uint64_t kMaxReadFileBytes = std::uint64_t{1} << 30; // 1 GiB

// What a path that is not a regular file is, for messages ("a directory"); "" if it is one.
inline std::string notRegularFile(const std::filesystem::file_status& st) {
    namespace fs = std::filesystem;
    switch (st.type()) {
    case fs::file_type::regular: return "";
    case fs::file_type::directory: return "a directory";
    case fs::file_type::fifo: return "a FIFO (named pipe)";
    case fs::file_type::character: return "a character device";
    case fs::file_type::block: return "a block device";
    case fs::file_type::socket: return "a socket";
    case fs::file_type::not_found: return "it does not exist";
    default: return "of another kind";
    }
}

// Throws FileError "<verb><what> '<path>': <why>". One function for the error paths of
// readFileBytes: inlined message building there set off GCC 12's -Warray-bounds false positive
// in callers.
[[noreturn]] inline void throwFileError(const char* verb, const char* what, const std::string& path, const std::string& why) {
    throw FileError(std::string(verb) + what + " '" + path + "': " + why);
}

/// Appends x in the shortest decimal form that reads back to the same double (OBJ writers).
inline void appendNumber(std::string& s, double x) {
    char buf[32];
    const auto r = std::to_chars(buf, buf + sizeof buf, x);
    s.append(buf, r.ptr);
}

// The whole content of a file. Only regular files are read: a directory, FIFO, device or socket
// is refused before it is opened (opening a FIFO would wait for a writer, and /dev/zero never
// ends). A file above maxBytes is refused from its size before anything is read, and the read
// stops at maxBytes + 1 bytes in case the file grows meanwhile. Throws FileError
// "cannot open/read <what> '<path>': reason".
inline std::vector<unsigned char> readFileBytes(const std::string& path, const char* what,
                                                std::uint64_t maxBytes = kMaxReadFileBytes) {
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (ec) throwFileError("cannot open ", what, path, ec.message());
    if (st.type() == std::filesystem::file_type::not_found) throwFileError("cannot open ", what, path, std::strerror(ENOENT));
    if (st.type() != std::filesystem::file_type::regular)
        throwFileError("cannot open ", what, path, "is not a regular file (" + notRegularFile(st) + ")");
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    const auto tooLarge = [&](const char* which, std::uint64_t bytes) {
        throwFileError("cannot read ", what, path,
                       std::string(which) + std::to_string(bytes) + " bytes is more than the " + std::to_string(maxBytes) +
                           " bytes a " + what + " may have");
    };
    if (!ec && size > maxBytes) tooLarge("", size);

    FilePtr f(std::fopen(path.c_str(), "rb"));
    if (!f) throwFileError("cannot open ", what, path, std::strerror(errno));
    std::vector<unsigned char> bytes;
    if (!ec) bytes.reserve(static_cast<std::size_t>(size));
    unsigned char chunk[16384];
    for (;;) {
        const std::size_t n = std::fread(chunk, 1, sizeof chunk, f.get());
        bytes.insert(bytes.end(), chunk, chunk + n);
        if (bytes.size() > maxBytes) tooLarge("the file grew while it was read: ", bytes.size());
        if (n < sizeof chunk) break;
    }
    if (std::ferror(f.get())) throwFileError("cannot read ", what, path, std::strerror(errno));
    return bytes;
}

// Throws FileError "cannot write <what> '<path>': it exists and is not a regular file (...)"
// when something other than a regular file is at path: renaming over a device, FIFO or socket
// would replace it with a regular file (as root, `-o /dev/null` would replace /dev/null).
// writeFileAtomically checks it; a program checks its output paths with it before its work.
inline void checkOutputPath(const std::string& path, const char* what) {
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (!ec && std::filesystem::exists(st) && st.type() != std::filesystem::file_type::regular)
        throw FileError(std::string("cannot write ") + what + " '" + path + "': it exists and is not a regular file (" +
                        notRegularFile(st) + ")");
}

// Replaces (or creates) the regular file at path with bytes, atomically (an existing directory,
// device, FIFO or socket at path is a FileError, left as it is): the bytes go to a new
// temporary file next to it, which is then renamed over path. On failure the temporary is
// removed, an existing file is left as it was, and FileError names path and the reason.
inline void writeFileAtomically(const std::string& path, const std::vector<unsigned char>& bytes,
                                const char* what) {
    const auto fail = [&](const std::string& why) {
        return FileError(std::string("cannot write ") + what + " '" + path + "': " + why);
    };
    checkOutputPath(path, what);
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

// Where a JSON text nests arrays and objects deeper than maxDepth (the byte offset of the
// bracket that goes too deep), or npos. Brackets inside strings and comments do not count;
// a malformed text is left for the parser to report. (A check before nlohmann-json parses: its
// parser recurses per level, so a hostile file of a million '[' must be refused first.)
inline std::size_t jsonTooDeepAt(std::string_view text, int maxDepth) {
    int depth = 0;
    for (std::size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (c == '"') {
            for (++i; i < text.size() && text[i] != '"'; ++i)
                if (text[i] == '\\') ++i;
        } else if (c == '/' && i + 1 < text.size() && text[i + 1] == '/') {
            while (i < text.size() && text[i] != '\n') ++i;
        } else if (c == '/' && i + 1 < text.size() && text[i + 1] == '*') {
            const std::size_t end = text.find("*/", i + 2);
            if (end == std::string_view::npos) return std::string_view::npos;
            i = end + 1;
        } else if (c == '[' || c == '{') {
            if (++depth > maxDepth) return i;
        } else if ((c == ']' || c == '}') && depth > 0) {
            --depth;
        }
    }
    return std::string_view::npos;
}

} // namespace dispmap::detail
