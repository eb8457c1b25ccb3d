// json_reader.hpp: strict, path-aware reading of JSON objects for scene files.
//
// Each accessor records the key it was asked for, so finish() can reject any key nobody
// asked for: a typo like "spacng" is an error, not a silently ignored field. Every message
// starts with the field's path ("cloth.sheet.rows: ...").
#pragma once

#include "drape_samples/scene.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

namespace drape::samples::detail {

using Json = nlohmann::json;

enum class Range { Any, Positive, NonNegative, UnitInterval };

inline std::string typeName(const Json& j) {
    return j.type_name();
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

    /// " (is \"spacng\" a misspelling of it?)" when a present key is within two edits of `key`.
    std::string misspellingHint(const std::string& key) const {
        for (auto it = j_.begin(); it != j_.end(); ++it)
            if (editDistance(it.key(), key) <= 2)
                return " (is \"" + it.key() + "\" a misspelling of it?)";
        return {};
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

    double toNumber(const Json& v, const std::string& path, Range r) const {
        if (!v.is_number()) fail(path, "expected a number, got " + typeName(v));
        const double x = v.get<double>();
        if (!std::isfinite(x)) fail(path, "must be finite");
        switch (r) {
        case Range::Any:
            break;
        case Range::Positive:
            if (!(x > 0.0)) fail(path, "must be > 0, got " + fmt(x));
            break;
        case Range::NonNegative:
            if (!(x >= 0.0)) fail(path, "must be >= 0, got " + fmt(x));
            break;
        case Range::UnitInterval:
            if (!(x >= 0.0 && x <= 1.0)) fail(path, "must be in [0, 1], got " + fmt(x));
            break;
        }
        return x;
    }
    double number(const std::string& key, double def, Range r = Range::Any) {
        const Json* v = find(key);
        return v ? toNumber(*v, pathOf(key), r) : def;
    }
    double requireNumber(const std::string& key, Range r = Range::Any) {
        return toNumber(require(key), pathOf(key), r);
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

    Vec3 toVec3(const Json& v, const std::string& path) const {
        if (!v.is_array() || v.size() != 3)
            fail(path,
                 "expected an array of 3 numbers, got " +
                     (v.is_array() ? "an array of " + std::to_string(v.size()) : typeName(v)));
        Vec3 r;
        for (int i = 0; i < 3; ++i)
            r[i] = toNumber(v[static_cast<std::size_t>(i)], path + "[" + std::to_string(i) + "]",
                            Range::Any);
        return r;
    }
    Vec3 vec3(const std::string& key, const Vec3& def) {
        const Json* v = find(key);
        return v ? toVec3(*v, pathOf(key)) : def;
    }
    Vec3 requireVec3(const std::string& key) { return toVec3(require(key), pathOf(key)); }

    Color color(const std::string& key, const Color& def) {
        const Json* v = find(key);
        if (!v) return def;
        const Vec3 c = toVec3(*v, pathOf(key));
        Color out{};
        for (int i = 0; i < 3; ++i) {
            if (c[i] < 0.0 || c[i] > 1.0)
                fail(pathOf(key) + "[" + std::to_string(i) + "]",
                     "colour components are in [0, 1]");
            out[static_cast<std::size_t>(i)] = static_cast<float>(c[i]);
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
            std::string list;
            for (const auto& k : known_)
                list += (list.empty() ? "" : ", ") + k;
            fail(pathOf(it.key()), "unknown field (fields allowed here: " + list + ")");
        }
    }

    const std::string& origin() const { return origin_; }

    static std::string fmt(double x) {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%g", x);
        return buf;
    }

  private:
    const Json& j_;
    std::string path_;
    std::string origin_;
    std::set<std::string> known_;
};

} // namespace drape::samples::detail
