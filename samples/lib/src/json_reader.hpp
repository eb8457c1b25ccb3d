// json_reader.hpp: strict, path-aware reading of JSON objects for scene files.
//
// parseJson refuses a key that appears twice in one object (naming it with its path).
// Each object declares the keys it knows (keys()) before anything is read from it, so an
// unknown key (a typo like "stifness") is reported first, with the known key it is closest
// to, never as a "missing field". Each accessor also records the key it was asked for, so
// finish() rejects any key nobody asked for. Numbers are checked against a physical range
// (Limits) that the message names. Every message starts with the field's path
// ("cloth.sheet.rows: ...").
#pragma once

#include "drape_samples/scene.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace drape::samples::detail {

using Json = nlohmann::json;

/// The physical range of a number: [lo, hi], either end open when asked, and its unit for
/// messages (SCENES.md lists the same ranges).
struct Limits {
    double lo;
    double hi;
    const char* unit = "";
    bool openLo = false;
    bool openHi = false;
};

inline std::string fmtNumber(double x) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
}

/// "[1e-06, 100000] m", "(0, 179) degrees".
inline std::string describe(const Limits& l) {
    std::string s = std::string(l.openLo ? "(" : "[") + fmtNumber(l.lo) + ", " + fmtNumber(l.hi) +
                    (l.openHi ? ")" : "]");
    if (l.unit && *l.unit) s += std::string(" ") + l.unit;
    return s;
}

inline bool within(double x, const Limits& l) {
    const bool aboveLo = l.openLo ? x > l.lo : x >= l.lo;
    const bool belowHi = l.openHi ? x < l.hi : x <= l.hi;
    return aboveLo && belowHi;
}

inline std::string typeName(const Json& j) {
    return j.type_name();
}

/// The deepest nesting of objects and arrays a scene file may have (a scene needs 5).
inline constexpr std::size_t kMaxJsonDepth = 64;

/// A SAX pass over the text that keeps no values: refuses a key given twice in one object,
/// nesting deeper than kMaxJsonDepth (before any memory is spent on it) and strings holding a
/// NUL character (no name or file name can: a path cut at the NUL would name another file).
/// Linear in the text (nlohmann's callback parser scans an array's elements again after each
/// object in it: quadratic for a long array of objects).
class JsonChecker final : public nlohmann::json_sax<Json> {
  public:
    explicit JsonChecker(std::string origin) : origin_(std::move(origin)) {}
    bool null() override { return done(); }
    bool boolean(bool) override { return done(); }
    bool number_integer(number_integer_t) override { return done(); }
    bool number_unsigned(number_unsigned_t) override { return done(); }
    bool number_float(number_float_t, const string_t&) override { return done(); }
    bool string(string_t& v) override {
        if (v.find('\0') != string_t::npos)
            fail("holds a NUL character (\\u0000); no name or file name can");
        return done();
    }
    bool binary(binary_t&) override { return done(); }
    bool start_object(std::size_t) override { return open(false); }
    bool key(string_t& k) override {
        Frame& top = stack_.back();
        top.key = k;
        if (k.find('\0') != string_t::npos) fail("a key holds a NUL character (\\u0000)");
        if (!top.keys.insert(k).second)
            fail("duplicate key (the object sets \"" + k + "\" more than once; give it once)");
        return true;
    }
    bool end_object() override { return close(); }
    bool start_array(std::size_t) override { return open(true); }
    bool end_array() override { return close(); }
    /// A syntax error: the caller parses again to get nlohmann's message (line and column).
    bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
        return false;
    }

  private:
    struct Frame {
        bool array = false;
        std::size_t index = 0; // arrays: the element being read
        std::string key;       // objects: the key being read
        std::set<std::string> keys;
    };
    bool open(bool array) {
        if (stack_.size() >= kMaxJsonDepth)
            fail("nested deeper than " + std::to_string(kMaxJsonDepth) +
                 " objects and arrays; a scene needs a handful");
        stack_.push_back(Frame{});
        stack_.back().array = array;
        return true;
    }
    bool close() {
        stack_.pop_back();
        return done();
    }
    bool done() {
        if (!stack_.empty() && stack_.back().array) ++stack_.back().index;
        return true;
    }
    [[noreturn]] void fail(const std::string& what) const {
        std::string p;
        for (const Frame& f : stack_)
            p += f.array ? "[" + std::to_string(f.index) + "]" : (p.empty() ? "" : ".") + f.key;
        throw SceneError(origin_ + ": " + (p.empty() ? std::string("(top level)") : p) + ": " +
                         what);
    }
    std::string origin_;
    std::vector<Frame> stack_;
};

/// Parses JSON text after JsonChecker's pass. Throws SceneError naming `origin` and the path;
/// nlohmann's own exceptions (syntax errors, numbers out of range) pass through to the caller.
inline Json parseJson(const std::string& text, const std::string& origin) {
    JsonChecker checker(origin);
    Json::sax_parse(text, &checker); // false on a syntax error: parse() below names it
    return Json::parse(text);
}

class JsonObject {
  public:
    JsonObject(const Json& j, std::string path, std::string origin)
        : j_(j), path_(std::move(path)), origin_(std::move(origin)) {
        if (!j_.is_object()) fail(path_, "expected an object, got " + typeName(j_));
    }

    const std::string& path() const { return path_; }
    std::string pathOf(const std::string& key) const {
        return path_.empty() ? key : path_ + "." + key;
    }

    [[noreturn]] void fail(const std::string& path, const std::string& what) const {
        throw SceneError(origin_ + ": " + (path.empty() ? std::string("(top level)") : path) +
                         ": " + what);
    }
    [[noreturn]] void failKey(const std::string& key, const std::string& what) const {
        fail(pathOf(key), what);
    }

    /// Declares every key this object may hold and refuses any other at once, with the
    /// declared key it is closest to ("did you mean"), before any field is read: a typo is
    /// never reported as a missing field.
    void keys(std::initializer_list<const char*> allowed) {
        for (const char* k : allowed)
            allowed_.insert(k);
        for (auto it = j_.begin(); it != j_.end(); ++it) {
            if (allowed_.count(it.key())) continue;
            fail(pathOf(it.key()), unknownFieldMessage(it.key(), allowed_));
        }
    }

    bool has(const std::string& key) {
        known_.insert(key);
        return j_.contains(key);
    }
    const Json* find(const std::string& key) {
        known_.insert(key);
        auto it = j_.find(key);
        return it == j_.end() ? nullptr : &*it;
    }
    const Json& require(const std::string& key) {
        const Json* v = find(key);
        if (!v) failKey(key, "required field is missing" + misspellingHint(key));
        return *v;
    }

    /// " (is \"spacng\" a misspelling of it?)" when a present key that is not one of this
    /// object's own keys is within two edits of `key`.
    std::string misspellingHint(const std::string& key) const {
        for (auto it = j_.begin(); it != j_.end(); ++it)
            if (!allowed_.count(it.key()) && editDistance(lower(it.key()), lower(key)) <= 2)
                return " (is \"" + it.key() + "\" a misspelling of it?)";
        return {};
    }

    /// The allowed key closest to `key` (case ignored), if it is within two edits and
    /// shorter than the key itself; empty if none is.
    static std::string suggestion(const std::string& key, const std::set<std::string>& allowed) {
        std::string best;
        std::size_t bestDistance = 3;
        for (const auto& a : allowed) {
            const std::size_t d = editDistance(lower(key), lower(a));
            if (d < bestDistance && d < std::max(key.size(), a.size())) {
                bestDistance = d;
                best = a;
            }
        }
        return best;
    }

    static std::string unknownFieldMessage(const std::string& key,
                                           const std::set<std::string>& allowed) {
        std::string list;
        for (const auto& k : allowed)
            list += (list.empty() ? "" : ", ") + k;
        const std::string near = suggestion(key, allowed);
        return "unknown field (" +
               (near.empty() ? std::string() : "did you mean \"" + near + "\"? ") +
               "fields allowed here: " + list + ")";
    }

    static std::string lower(std::string s) {
        for (char& c : s)
            c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        return s;
    }

    static std::size_t editDistance(const std::string& a, const std::string& b) {
        std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
        for (std::size_t j = 0; j <= b.size(); ++j)
            prev[j] = j;
        for (std::size_t i = 1; i <= a.size(); ++i) {
            cur[0] = i;
            for (std::size_t j = 1; j <= b.size(); ++j)
                cur[j] = std::min(
                    {prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0u : 1u)});
            std::swap(prev, cur);
        }
        return prev[b.size()];
    }

    /// The number at `path`; it must lie within `l` (the message names the range).
    double toNumber(const Json& v, const std::string& path, const Limits& l) const {
        if (!v.is_number()) fail(path, "expected a number, got " + typeName(v));
        const double x = v.get<double>();
        if (!std::isfinite(x)) fail(path, "must be finite");
        if (!within(x, l)) fail(path, "must be in " + describe(l) + ", got " + fmt(x));
        return x;
    }
    double number(const std::string& key, double def, const Limits& l) {
        const Json* v = find(key);
        return v ? toNumber(*v, pathOf(key), l) : def;
    }
    /// The number at `key` within `l`, or nothing when the key is absent.
    std::optional<double> optNumber(const std::string& key, const Limits& l) {
        const Json* v = find(key);
        if (!v) return std::nullopt;
        return toNumber(*v, pathOf(key), l);
    }
    double requireNumber(const std::string& key, const Limits& l) {
        return toNumber(require(key), pathOf(key), l);
    }

    long long toInteger(const Json& v, const std::string& path, long long lo, long long hi) const {
        if (!v.is_number_integer() && !v.is_number_unsigned()) {
            if (v.is_number_float()) fail(path, "expected an integer, got " + v.dump());
            fail(path, "expected an integer, got " + typeName(v));
        }
        if (v.is_number_unsigned() &&
            v.get<unsigned long long>() > static_cast<unsigned long long>(hi))
            fail(path, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
                           v.dump());
        const long long x = v.get<long long>();
        if (x < lo || x > hi)
            fail(path, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
                           std::to_string(x));
        return x;
    }
    long long integer(const std::string& key, long long def, long long lo, long long hi) {
        const Json* v = find(key);
        return v ? toInteger(*v, pathOf(key), lo, hi) : def;
    }

    bool boolean(const std::string& key, bool def) {
        const Json* v = find(key);
        if (!v) return def;
        if (!v->is_boolean()) failKey(key, "expected true or false, got " + typeName(*v));
        return v->get<bool>();
    }

    std::string string(const std::string& key, const std::string& def) {
        const Json* v = find(key);
        if (!v) return def;
        if (!v->is_string()) failKey(key, "expected a string, got " + typeName(*v));
        return v->get<std::string>();
    }
    std::string requireString(const std::string& key) {
        const Json& v = require(key);
        if (!v.is_string()) failKey(key, "expected a string, got " + typeName(v));
        return v.get<std::string>();
    }
    /// A string that must be one of `choices`.
    std::string choice(const std::string& key, const std::string& def,
                       const std::vector<std::string>& choices) {
        const std::string s = string(key, def);
        for (const auto& c : choices)
            if (c == s) return s;
        std::string list;
        for (const auto& c : choices)
            list += (list.empty() ? "" : ", ") + ("\"" + c + "\"");
        failKey(key, "unknown value \"" + s + "\" (expected one of " + list + ")");
    }

    /// [x, y, z], each component within `l` (the message names the component).
    Vec3 toVec3(const Json& v, const std::string& path, const Limits& l) const {
        if (!v.is_array() || v.size() != 3)
            fail(path,
                 "expected an array of 3 numbers, got " +
                     (v.is_array() ? "an array of " + std::to_string(v.size()) : typeName(v)));
        Vec3 r;
        for (int i = 0; i < 3; ++i)
            r[i] =
                toNumber(v[static_cast<std::size_t>(i)], path + "[" + std::to_string(i) + "]", l);
        return r;
    }
    Vec3 vec3(const std::string& key, const Vec3& def, const Limits& l) {
        const Json* v = find(key);
        return v ? toVec3(*v, pathOf(key), l) : def;
    }
    Vec3 requireVec3(const std::string& key, const Limits& l) {
        return toVec3(require(key), pathOf(key), l);
    }

    Color color(const std::string& key, const Color& def) {
        const Json* v = find(key);
        if (!v) return def;
        if (!v->is_array() || v->size() != 3)
            failKey(key, "expected an array of 3 numbers, got " +
                             (v->is_array() ? "an array of " + std::to_string(v->size())
                                            : typeName(*v)));
        Color out{};
        for (std::size_t i = 0; i < 3; ++i) {
            const std::string p = pathOf(key) + "[" + std::to_string(i) + "]";
            if (!(*v)[i].is_number()) fail(p, "expected a number, got " + typeName((*v)[i]));
            const double c = (*v)[i].get<double>();
            if (!(c >= 0.0 && c <= 1.0)) fail(p, "colour components are in [0, 1], got " + fmt(c));
            out[i] = static_cast<float>(c);
        }
        return out;
    }

    JsonObject object(const std::string& key) {
        return JsonObject(require(key), pathOf(key), origin_);
    }
    std::optional<JsonObject> optObject(const std::string& key) {
        const Json* v = find(key);
        if (!v) return std::nullopt;
        return JsonObject(*v, pathOf(key), origin_);
    }
    /// The array at key (empty when absent); fails if present and not an array.
    const Json& array(const std::string& key, std::size_t maxSize) {
        static const Json empty = Json::array();
        const Json* v = find(key);
        if (!v) return empty;
        if (!v->is_array()) failKey(key, "expected an array, got " + typeName(*v));
        if (v->size() > maxSize)
            failKey(key, "too many entries (" + std::to_string(v->size()) + ", limit " +
                             std::to_string(maxSize) + ")");
        return *v;
    }

    /// Rejects every key that no accessor asked for.
    void finish() const {
        for (auto it = j_.begin(); it != j_.end(); ++it) {
            if (known_.count(it.key())) continue;
            fail(pathOf(it.key()), unknownFieldMessage(it.key(), known_));
        }
    }

    const std::string& origin() const { return origin_; }

    static std::string fmt(double x) { return fmtNumber(x); }

  private:
    const Json& j_;
    std::string path_;
    std::string origin_;
    std::set<std::string> known_;   // keys an accessor asked for
    std::set<std::string> allowed_; // keys declared with keys()
};

} // namespace drape::samples::detail
