// dispmap_glslgen: writes the GLSL mirror of the C++ kernel headers (docs/design.md, "Kernels
// written once"). It never translates: it copies the text between
//     // dispmap:glsl-begin [double]      and      // dispmap:glsl-end
// verbatim, adds a header, an include guard, the includes of the kernel headers it depends
// on and `#line` directives pointing back at the C++ file, and wraps it in the precision
// macros of the GLSL prelude (which it also writes, as prelude.glsl). A float variant is
// always written; a double variant (behind DM_ENABLE_DOUBLE) when the begin marker says
// `double`, holding the DM_TFUNC items only: DM_FUNC items have no precision and are
// written once.
//
// Before writing anything it checks the marked text against the subset that means the same
// in C++ and GLSL and refuses anything else with file:line. Usage:
//     dispmap_glslgen --out DIR [--root ROOT] header.h...    write DIR/<name>.glsl
//     dispmap_glslgen --verify DIR [--root ROOT] header.h... compare with DIR, list stale files
//     dispmap_glslgen --check-shaders DIR header.h...        write one check .comp per include
// ROOT is stripped from the paths written into #line directives and headers.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct GenError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

[[noreturn]] void fail(const std::string& file, int line, const std::string& what) {
    throw GenError(file + ":" + std::to_string(line) + ": error: " + what);
}

std::string readText(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    if (!in) throw GenError(p.string() + ": cannot read");
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

std::vector<std::string> splitLines(const std::string& text) {
    std::vector<std::string> lines;
    std::string cur;
    for (char c : text) {
        if (c == '\n') {
            lines.push_back(cur);
            cur.clear();
        } else if (c != '\r') {
            cur += c;
        }
    }
    if (!cur.empty()) lines.push_back(cur);
    return lines;
}

// ---------------------------------------------------------------------------------------
// Tokens of the marked text (comments dropped, line numbers kept).
struct Token {
    enum Kind { Ident, Number, Punct } kind;
    std::string text;
    int line; // 1-based line in the C++ file
};

bool isIdentStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_'; }
bool isIdentChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

std::vector<Token> tokenize(const std::vector<std::string>& lines, int first, int last, const std::string& file) {
    std::vector<Token> out;
    bool inBlockComment = false;
    static const char* const twoChar[] = {"::", "->", "&&", "||", "==", "!=", "<=", ">=", "<<", ">>", "++", "--",
                                          "+=", "-=", "*=", "/=", "&=", "|=", "^=", "%="};
    for (int ln = first; ln < last; ++ln) {
        const std::string& s = lines[static_cast<std::size_t>(ln)];
        const int lineNo = ln + 1;
        std::size_t i = 0;
        while (i < s.size()) {
            if (inBlockComment) {
                std::size_t e = s.find("*/", i);
                if (e == std::string::npos) {
                    i = s.size();
                } else {
                    inBlockComment = false;
                    i = e + 2;
                }
                continue;
            }
            char c = s[i];
            if (std::isspace(static_cast<unsigned char>(c))) {
                ++i;
            } else if (s.compare(i, 2, "//") == 0) {
                break;
            } else if (s.compare(i, 2, "/*") == 0) {
                inBlockComment = true;
                i += 2;
            } else if (c == '#') {
                fail(file, lineNo, "preprocessor directives are not allowed inside the marked kernel text");
            } else if (c == '"' || c == '\'') {
                fail(file, lineNo, "string and character literals are not in the GLSL subset");
            } else if (isIdentStart(c)) {
                std::size_t j = i;
                while (j < s.size() && isIdentChar(s[j])) ++j;
                out.push_back({Token::Ident, s.substr(i, j - i), lineNo});
                i = j;
            } else if (std::isdigit(static_cast<unsigned char>(c)) ||
                       (c == '.' && i + 1 < s.size() && std::isdigit(static_cast<unsigned char>(s[i + 1])))) {
                std::size_t j = i;
                while (j < s.size() && (isIdentChar(s[j]) || s[j] == '.' ||
                                        ((s[j] == '+' || s[j] == '-') && (s[j - 1] == 'e' || s[j - 1] == 'E') &&
                                         s.compare(i, 2, "0x") != 0)))
                    ++j;
                out.push_back({Token::Number, s.substr(i, j - i), lineNo});
                i = j;
            } else {
                std::string p(1, c);
                for (const char* t : twoChar)
                    if (s.compare(i, 2, t) == 0) p = t;
                out.push_back({Token::Punct, p, lineNo});
                i += p.size();
            }
        }
    }
    return out;
}

// ---------------------------------------------------------------------------------------
// The subset.
const std::set<std::string> kBannedWords = {
    // C++ that GLSL lacks
    "template", "typename", "class", "namespace", "using", "auto", "constexpr", "consteval", "static", "extern",
    "nullptr", "new", "delete", "sizeof", "static_cast", "reinterpret_cast", "const_cast", "dynamic_cast", "std",
    "operator", "this", "throw", "try", "catch", "goto", "union", "enum", "virtual", "private", "public",
    "protected", "friend", "mutable", "inline", "long", "short", "unsigned", "signed", "char", "size_t",
    // GLSL words that C++ would take as names (or that need the prelude's spelling)
    "in", "out", "inout", "input", "output", "sample", "patch", "filter", "common", "partition", "active", "smooth",
    "flat", "noperspective", "centroid", "layout", "attribute", "varying", "buffer", "shared", "coherent",
    "volatile", "restrict", "readonly", "writeonly", "precise", "subroutine", "invariant", "lowp", "mediump",
    "highp", "precision", "discard", "uniform", "texture", "superp", "packed", "resource", "external"};

const std::set<std::string> kTypeWords = {"void",  "bool",  "int",   "uint",  "float", "double", "real",
                                          "rvec2", "rvec3", "rvec4", "rmat3", "vec2",  "vec3",   "vec4",
                                          "ivec2", "ivec3", "ivec4", "uvec2", "uvec3", "uvec4",  "bvec2",
                                          "bvec3", "bvec4", "mat2",  "mat3",  "mat4",  "dvec2",  "dvec3",
                                          "dvec4", "dmat2", "dmat3", "dmat4"};
const std::set<std::string> kRealTypes = {"real", "rvec2", "rvec3", "rvec4", "rmat3"};

bool isSwizzle(const std::string& s) {
    if (s.size() < 2 || s.size() > 4) return false;
    for (const char* set : {"xyzw", "rgba", "stpq"}) {
        bool all = true;
        for (char c : s) all = all && std::string(set).find(c) != std::string::npos;
        if (all) return true;
    }
    return false;
}

bool isFloatLiteral(const std::string& n) {
    if (n.rfind("0x", 0) == 0 || n.rfind("0X", 0) == 0) return false;
    return n.find('.') != std::string::npos || n.find('e') != std::string::npos || n.find('E') != std::string::npos;
}

// One top-level item of the marked text: a function (or a const/struct declaration) with
// the comment lines above it.
struct Item {
    int firstLine = 0;    // 0-based index of its first line (leading comments included)
    int lastLine = 0;     // 0-based index one past its last line
    std::string storage;  // "DM_FUNC", "DM_TFUNC" or "" (not a function)
    std::string name;     // function name
    std::set<std::string> calls;
    int declLine = 0;
};

void checkTokens(const std::vector<Token>& t, const std::string& file) {
    for (std::size_t i = 0; i < t.size(); ++i) {
        const Token& k = t[i];
        const Token* prev = i > 0 ? &t[i - 1] : nullptr;
        const Token* next = i + 1 < t.size() ? &t[i + 1] : nullptr;
        if (k.kind == Token::Ident && kBannedWords.count(k.text))
            fail(file, k.line, "'" + k.text + "' is outside the C++/GLSL kernel subset (see kernels/prelude.h)");
        if (k.kind == Token::Punct) {
            if (k.text == "::") fail(file, k.line, "'::' (namespaces, static members) is not GLSL");
            if (k.text == "->") fail(file, k.line, "'->' (pointers) is not GLSL");
            if (k.text == "&" && prev && prev->kind == Token::Ident &&
                (kTypeWords.count(prev->text) || prev->text == "const"))
                fail(file, k.line, "references are not GLSL: use DM_OUT(T) or DM_INOUT(T) for outputs");
            if (k.text == "*" && prev && prev->kind == Token::Ident && kTypeWords.count(prev->text) && next &&
                next->kind == Token::Ident)
                fail(file, k.line, "pointers are not GLSL");
            if (k.text == "{" && prev &&
                (prev->text == "=" || prev->text == "(" || prev->text == "," || prev->text == "return" ||
                 (prev->kind == Token::Ident && prev->text != "else" && prev->text != "do" &&
                  !(i >= 2 && t[i - 2].text == "struct"))))
                fail(file, k.line, "brace initialisation is not GLSL: call the constructor or assign fields");
            if (k.text == "." && next && next->kind == Token::Ident && isSwizzle(next->text))
                fail(file, k.line, "swizzle '." + next->text + "': GLM has swizzles off; build the vector");
            if (k.text == "[" && next && next->text == "]")
                fail(file, k.line, "unsized arrays are not in the kernel subset");
        }
        if (k.kind == Token::Number) {
            std::string low = k.text;
            std::transform(low.begin(), low.end(), low.begin(), [](char c) { return static_cast<char>(std::tolower(c)); });
            bool hex = low.rfind("0x", 0) == 0;
            if (!hex && (low.back() == 'f' || low.back() == 'l'))
                fail(file, k.line, "literal '" + k.text + "' has a precision suffix: write real(" +
                                       k.text.substr(0, k.text.size() - (low.size() > 2 && low.substr(low.size() - 2) == "lf" ? 2 : 1)) +
                                       ") so it means the same at both precisions");
            if (low.find("ul") != std::string::npos || low.find("ll") != std::string::npos)
                fail(file, k.line, "64-bit integer literal '" + k.text + "' is not in the subset");
            if (isFloatLiteral(k.text)) {
                bool wrapped = prev && prev->text == "(" && i >= 2 && next && next->text == ")" &&
                               (t[i - 2].text == "real" || t[i - 2].text == "float" || t[i - 2].text == "double");
                bool negWrapped = prev && prev->text == "-" && i >= 3 && t[i - 2].text == "(" && next &&
                                  next->text == ")" &&
                                  (t[i - 3].text == "real" || t[i - 3].text == "float" || t[i - 3].text == "double");
                if (!wrapped && !negWrapped)
                    fail(file, k.line, "floating literal '" + k.text + "' must be written real(" + k.text +
                                           ") (or float(...)/double(...)): a bare literal is double in C++ and float in GLSL");
            }
        }
    }
}

// Splits the marked lines [first, last) into items and checks each function's shape.
std::vector<Item> splitItems(const std::vector<std::string>& lines, int first, int last, const std::string& file) {
    std::vector<Item> items;
    int ln = first;
    while (ln < last) {
        // Leading blank and comment lines belong to the next item.
        int start = ln;
        auto isCommentOrBlank = [&](int l) {
            std::string s = lines[static_cast<std::size_t>(l)];
            s.erase(0, s.find_first_not_of(" \t"));
            return s.empty() || s.rfind("//", 0) == 0;
        };
        while (ln < last && isCommentOrBlank(ln)) ++ln;
        if (ln == last) break;
        int depth = 0;
        int end = ln;
        bool done = false;
        // Scan lines until the item closes: a '}' back at depth 0 or a ';' at depth 0.
        std::vector<Token> toks;
        while (end < last && !done) {
            std::vector<Token> lt = tokenize(lines, end, end + 1, file);
            for (const Token& tk : lt) {
                toks.push_back(tk);
                if (tk.text == "{") ++depth;
                if (tk.text == "}") {
                    if (--depth == 0) done = true;
                }
                if (tk.text == ";" && depth == 0) done = true;
            }
            ++end;
        }
        if (!done) fail(file, ln + 1, "kernel item does not end before dispmap:glsl-end (unbalanced braces?)");
        Item it;
        it.firstLine = start;
        it.lastLine = end;
        it.declLine = ln + 1;
        if (!toks.empty() && (toks[0].text == "DM_FUNC" || toks[0].text == "DM_TFUNC")) {
            it.storage = toks[0].text;
            // storage, return type, name, '(' params ')' '{'
            std::size_t p = 1;
            while (p < toks.size() && toks[p].text != "(") ++p;
            if (p < 2 || p >= toks.size()) fail(file, it.declLine, "cannot read the function declaration");
            it.name = toks[p - 1].text;
            if (it.name.rfind("dm", 0) != 0)
                fail(file, it.declLine, "kernel function '" + it.name + "' must carry the dm prefix (GLSL has no namespaces)");
            int pd = 0;
            bool hasReal = false;
            std::size_t q = p;
            for (; q < toks.size(); ++q) {
                if (toks[q].text == "(") ++pd;
                if (toks[q].text == ")" && --pd == 0) break;
                if (toks[q].text == "=") fail(file, toks[q].line, "default arguments are not GLSL");
                if (kRealTypes.count(toks[q].text)) hasReal = true;
            }
            if (it.storage == "DM_TFUNC" && !hasReal)
                fail(file, it.declLine, "DM_TFUNC '" + it.name + "' needs a real-typed parameter (C++ deduces the precision from it, GLSL overloads on it)");
            for (std::size_t c = q; c + 1 < toks.size(); ++c)
                if (toks[c].kind == Token::Ident && toks[c + 1].text == "(" && toks[c].text.rfind("dm", 0) == 0)
                    it.calls.insert(toks[c].text);
        } else if (!toks.empty() && toks[0].kind == Token::Ident && toks.size() > 2 && toks[2].text == "(") {
            fail(file, it.declLine, "a kernel function must be declared DM_FUNC or DM_TFUNC");
        }
        checkTokens(toks, file);
        items.push_back(it);
        ln = end;
    }
    return items;
}

struct Header {
    fs::path path;
    std::string display; // path written into the output
    std::string stem;
    std::vector<std::string> lines;
    std::vector<std::string> deps; // stems of kernel headers it includes
    int begin = -1, end = -1;      // 0-based marker lines
    bool doubleVariant = false;
    std::string checkWith; // a GLSL file (shaders/-relative) that includes this one: the check shader's include
    std::vector<Item> items;
};

Header readHeader(const fs::path& p, const fs::path& root) {
    Header h;
    h.path = p;
    std::error_code ec;
    fs::path rel = root.empty() ? p : fs::relative(p, root, ec);
    h.display = (ec || rel.empty() ? p : rel).generic_string();
    h.stem = p.stem().string();
    h.lines = splitLines(readText(p));
    for (int i = 0; i < static_cast<int>(h.lines.size()); ++i) {
        std::string s = h.lines[static_cast<std::size_t>(i)];
        s.erase(0, s.find_first_not_of(" \t"));
        if (s.rfind("// dispmap:glsl-begin", 0) == 0) {
            if (h.begin >= 0) fail(h.display, i + 1, "second dispmap:glsl-begin (one marked region per header)");
            h.begin = i;
            std::istringstream opts(s.substr(std::string("// dispmap:glsl-begin").size()));
            for (std::string opt; opts >> opt;) {
                if (opt == "double") {
                    h.doubleVariant = true;
                } else if (opt == "check-with" && (opts >> h.checkWith)) {
                    // Kernels whose includer supplies declarations (kernels/meso_march.h: the
                    // maps and fetch functions) are checked through that includer.
                } else {
                    fail(h.display, i + 1, "unknown option '" + opt + "' (double, check-with FILE)");
                }
            }
        } else if (s.rfind("// dispmap:glsl-end", 0) == 0) {
            if (h.begin < 0 || h.end >= 0) fail(h.display, i + 1, "dispmap:glsl-end without a begin");
            h.end = i;
        } else if (s.rfind("#include \"", 0) == 0) {
            std::size_t a = s.find('"') + 1, b = s.find('"', a);
            std::string inc = s.substr(a, b - a);
            fs::path ip(inc);
            std::string st = ip.stem().string();
            if (h.begin >= 0 && h.end < 0) fail(h.display, i + 1, "#include inside the marked kernel text");
            if (st != "prelude" && st != "prelude_end") h.deps.push_back(st);
        }
    }
    if (h.begin < 0 || h.end < 0) fail(h.display, 1, "no '// dispmap:glsl-begin' ... '// dispmap:glsl-end' region");
    h.items = splitItems(h.lines, h.begin + 1, h.end, h.display);
    return h;
}

// Direct and indirect recursion among all kernel functions.
void checkRecursion(const std::vector<Header>& hs) {
    std::map<std::string, std::pair<const Item*, std::string>> fn;
    for (const Header& h : hs)
        for (const Item& it : h.items)
            if (!it.name.empty()) fn[it.name] = {&it, h.display};
    for (const auto& [name, entry] : fn) {
        std::set<std::string> seen;
        std::vector<std::string> stack(entry.first->calls.begin(), entry.first->calls.end());
        while (!stack.empty()) {
            std::string c = stack.back();
            stack.pop_back();
            if (c == name) fail(entry.second, entry.first->declLine, "'" + name + "' is recursive: GLSL forbids recursion");
            if (!seen.insert(c).second) continue;
            auto f = fn.find(c);
            if (f != fn.end()) stack.insert(stack.end(), f->second.first->calls.begin(), f->second.first->calls.end());
        }
    }
}

const char* const kPrecisionMacros[][3] = {
    {"real", "float", "double"}, {"rvec2", "vec2", "dvec2"}, {"rvec3", "vec3", "dvec3"},
    {"rvec4", "vec4", "dvec4"},  {"rmat3", "mat3", "dmat3"},
};

std::string guardName(const std::string& stem) {
    std::string g = "DISPMAP_GLSL_";
    for (char c : stem) g += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return g;
}

std::string precisionBlock(int variant) {
    std::string s;
    for (const auto& m : kPrecisionMacros) s += std::string("#define ") + m[0] + " " + m[variant] + "\n";
    return s;
}
std::string undefBlock() {
    std::string s;
    for (const auto& m : kPrecisionMacros) s += std::string("#undef ") + m[0] + "\n";
    return s;
}

std::string lineDirective(int line, const std::string& file) {
    return "#line " + std::to_string(line) + " \"" + file + "\"\n";
}

std::string emit(const Header& h) {
    std::ostringstream o;
    o << "// Generated by dispmap_glslgen from " << h.display << ". Do not edit: edit the C++ header;\n"
      << "// the build regenerates this file and the test glsl_generated_current compares it.\n"
      << "// Variants: float" << (h.doubleVariant ? ", double (define DM_ENABLE_DOUBLE)" : "") << ".\n"
      << "#ifndef " << guardName(h.stem) << "\n#define " << guardName(h.stem) << "\n"
      << "#include \"prelude.glsl\"\n";
    for (const std::string& d : h.deps) o << "#include \"" << d << ".glsl\"\n";
    o << precisionBlock(1) << lineDirective(h.begin + 2, h.display);
    for (int i = h.begin + 1; i < h.end; ++i) o << h.lines[static_cast<std::size_t>(i)] << "\n";
    o << undefBlock();
    if (h.doubleVariant) {
        o << "#ifdef DM_ENABLE_DOUBLE\n" << precisionBlock(2);
        for (const Item& it : h.items) {
            if (it.storage != "DM_TFUNC") continue;
            o << lineDirective(it.firstLine + 1, h.display);
            for (int i = it.firstLine; i < it.lastLine; ++i) o << h.lines[static_cast<std::size_t>(i)] << "\n";
        }
        o << undefBlock() << "#endif // DM_ENABLE_DOUBLE\n";
    }
    o << "#endif // " << guardName(h.stem) << "\n";
    return o.str();
}

std::string emitPrelude() {
    return "// Generated by dispmap_glslgen: the GLSL side of include/dispmap/kernels/prelude.h.\n"
           "// Include the kernel files (e.g. #include \"tile.glsl\") with GL_GOOGLE_include_directive;\n"
           "// define DM_ENABLE_DOUBLE before them for the double variants (needs shaderFloat64).\n"
           "#ifndef DISPMAP_GLSL_PRELUDE\n#define DISPMAP_GLSL_PRELUDE\n"
           "#extension GL_GOOGLE_cpp_style_line_directive : enable\n"
           "#define DM_FUNC\n#define DM_TFUNC\n#define DM_OUT(T) out T\n#define DM_INOUT(T) inout T\n"
           "#define DM_OUT_ARRAY(T) out T\n"
           "#endif // DISPMAP_GLSL_PRELUDE\n";
}

// A compute shader that only includes one generated file, with the double variants enabled:
// compiling it checks the float and the double text (and those of its dependencies).
// A kernel checked with an includer is compiled through that file (found on shaders/).
std::string emitCheckShader(const Header& h) {
    return "#version 450\n#extension GL_GOOGLE_include_directive : require\n#define DM_ENABLE_DOUBLE\n#include \"" +
           (h.checkWith.empty() ? h.stem + ".glsl" : h.checkWith) + "\"\nlayout(local_size_x = 1) in;\nvoid main() {}\n";
}

void writeIfChanged(const fs::path& p, const std::string& text) {
    std::error_code ec;
    if (fs::exists(p, ec)) {
        if (readText(p) == text) return;
    }
    fs::create_directories(p.parent_path());
    fs::path tmp = p;
    tmp += ".tmp";
    {
        std::ofstream out(tmp, std::ios::binary);
        out << text;
        if (!out) throw GenError(tmp.string() + ": cannot write");
    }
    fs::rename(tmp, p);
}

} // namespace

int main(int argc, char** argv) {
    try {
        std::string mode, dir;
        fs::path root;
        std::vector<fs::path> inputs;
        for (int i = 1; i < argc; ++i) {
            std::string a = argv[i];
            if ((a == "--out" || a == "--verify" || a == "--check-shaders") && i + 1 < argc) {
                mode = a;
                dir = argv[++i];
            } else if (a == "--root" && i + 1 < argc) {
                root = argv[++i];
            } else if (a.rfind("--", 0) == 0) {
                throw GenError("unknown option " + a);
            } else {
                inputs.emplace_back(a);
            }
        }
        if (mode.empty() || inputs.empty())
            throw GenError("usage: dispmap_glslgen --out|--verify|--check-shaders DIR [--root ROOT] header.h...");
        std::vector<Header> headers;
        for (const fs::path& p : inputs) {
            std::string stem = p.stem().string();
            if (stem == "prelude" || stem == "prelude_end") continue;
            headers.push_back(readHeader(p, root));
        }
        checkRecursion(headers);
        std::map<std::string, std::string> files;
        files["prelude.glsl"] = emitPrelude();
        for (const Header& h : headers) files[h.stem + ".glsl"] = emit(h);

        if (mode == "--out") {
            for (const auto& [name, text] : files) writeIfChanged(fs::path(dir) / name, text);
        } else if (mode == "--check-shaders") {
            for (const Header& h : headers) writeIfChanged(fs::path(dir) / ("check_" + h.stem + ".comp"), emitCheckShader(h));
        } else {
            int stale = 0;
            for (const auto& [name, text] : files) {
                fs::path p = fs::path(dir) / name;
                std::error_code ec;
                if (!fs::exists(p, ec) || readText(p) != text) {
                    std::cerr << p.string() << ": stale or missing; rebuild the target dispmap_update_glsl\n";
                    ++stale;
                }
            }
            for (const auto& e : fs::directory_iterator(dir)) {
                if (!files.count(e.path().filename().string())) {
                    std::cerr << e.path().string() << ": not generated from any kernel header; remove it\n";
                    ++stale;
                }
            }
            if (stale) return 1;
            std::cout << files.size() << " generated GLSL files current in " << dir << "\n";
        }
        return 0;
    } catch (const std::exception& e) {
        std::cerr << e.what() << "\n";
        return 1;
    }
}
