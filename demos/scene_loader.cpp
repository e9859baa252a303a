// tearables: the headless scene loader (docs/SCENE_FORMAT.md, "tearables-scene/1").
// Every field is checked where it is read; a bad one throws InvalidInput whose field() is the
// field's JSON path ("strings[0].material.tensile.rupture") and whose problem() says what is
// wrong and what was found.
#include "tearables/presets.hpp"
#include "tearables/scene.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cstdint>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace tearables::scene {

namespace {

using json = nlohmann::json;

constexpr const char* kFormat = "tearables-scene/1";
/// Bullet stores sizes, masses and inertias in single precision. A box's inertia is
/// m (a^2 + b^2) / 3 for half extents a, b: sizes in [1e-4, 1e6] m and masses in
/// [1e-6, 1e9] kg keep it in [3e-15, 7e20] kg m^2, and its inverse, finite normal floats
/// (FLT_MIN 1.2e-38, FLT_MAX 3.4e38). The inverse mass 1/m stays below 1e6.
constexpr double kMinSize = 1e-4;
constexpr double kMaxSize = 1e6;
constexpr double kMinBodyMass = 1e-6;
constexpr double kMaxBodyMass = 1e9;
/// Positions are bounded to +-1e6 m (Range::bullet); so are a plane's offset after
/// normalisation and the corners of a sheet or cloth.
constexpr double kMaxPosition = 1e6;
/// Scripted speeds (kMaxDriverSpeed, the particle speed clamp) and forces: a steel cable of
/// 5 cm radius tears near 8e6 N; 1e9 N leaves room and keeps the tensions far from overflow.
constexpr double kMaxSpeed = kMaxDriverSpeed;
constexpr double kMaxForce = kMaxDriverForce;
constexpr double kMaxRampRate = 1e9;  // N/s
/// A twist driver's rate, rad/s (a fast drill turns at 300 rad/s).
constexpr double kMaxTwistRate = 1e3;
/// A quaternion or a plane normal is normalised: its norm must be in this range.
constexpr double kMinNorm = 1e-6;
constexpr double kMaxNorm = 1e6;

/// Name -> path of the object that defined it (for "duplicate name" messages).
using NameMap = std::map<std::string, std::string>;

// =============================================================================================
// Paths and message text
// =============================================================================================

bool isIdentifier(const std::string& s) {
    if (s.empty() || std::isdigit(static_cast<unsigned char>(s[0]))) return false;
    return std::all_of(s.begin(), s.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

/// A string as a JSON string literal, for messages and paths.
std::string jsonQuoted(const std::string& s) {
    return json(s).dump(-1, ' ', false, json::error_handler_t::replace);
}

/// The path of member `key` of the object at `base`: `base.key`, or `base["key"]` when the
/// key is not an identifier (`particle_masses["-1"]`).
std::string memberPath(const std::string& base, const std::string& key) {
    if (isIdentifier(key)) return base.empty() ? key : base + "." + key;
    return base + "[" + jsonQuoted(key) + "]";
}

/// The path of element `index` of the array at `base`.
std::string elementPath(const std::string& base, std::size_t index) {
    return base + "[" + std::to_string(index) + "]";
}

std::string formatNumber(double v) {
    std::ostringstream s;
    s.precision(9);
    s << v;
    return s.str();
}

/// What a JSON value is, for "expected X, got Y" messages: "a string", "an array of 2 elements".
std::string describe(const json& v) {
    switch (v.type()) {
        case json::value_t::null: return "null";
        case json::value_t::boolean: return "a boolean";
        case json::value_t::string: return "a string";
        case json::value_t::object: return "an object";
        case json::value_t::array:
            return "an array of " + std::to_string(v.size()) + (v.size() == 1 ? " element" : " elements");
        case json::value_t::number_integer:
        case json::value_t::number_unsigned:
        case json::value_t::number_float: return "a number";
        default: return "a " + std::string(v.type_name());
    }
}

/// "a, b, c" from a list of names.
template <class Names>
std::string joinNames(const Names& names) {
    std::string out;
    for (const auto& n : names) out += (out.empty() ? "" : ", ") + std::string(n);
    return out;
}

/// " (bodies: a, b)" or " (the scene has no bodies)", to follow "no body named ...".
std::string knownNames(const std::vector<std::string>& names, const std::string& plural) {
    if (names.empty()) return " (the scene has no " + plural + ")";
    return " (" + plural + ": " + joinNames(names) + ")";
}

// =============================================================================================
// JSON text -> DOM, with the path of whatever the parser itself rejects
// =============================================================================================

/// A SAX handler that builds the DOM (like json::parse) while tracking the JSON path of the
/// value being read, so that what only the parser sees still names its place: numbers too
/// large for a double ("1e999") and duplicate keys. Syntax errors report line, column and byte.
class PathTrackingBuilder : public nlohmann::json_sax<json> {
public:
    json root;                          ///< the document, once parsing succeeded
    std::optional<InvalidInput> error;  ///< the first problem found

    bool null() override { return add(nullptr); }
    bool boolean(bool v) override { return add(v); }
    bool number_integer(number_integer_t v) override { return add(v); }
    bool number_unsigned(number_unsigned_t v) override { return add(v); }
    bool number_float(number_float_t v, const string_t& /*text*/) override { return add(v); }
    bool string(string_t& v) override { return add(std::move(v)); }
    bool binary(binary_t& v) override { return add(json::binary(v)); }
    bool start_object(std::size_t /*size*/) override { return open(json::object()); }
    bool start_array(std::size_t /*size*/) override { return open(json::array()); }
    bool end_object() override { return close(); }
    bool end_array() override { return close(); }

    bool key(string_t& k) override {
        Frame& f = stack_.back();
        f.key = k;
        if (f.value->contains(k)) {
            error.emplace(memberPath(f.path, k), "duplicate field (each field may appear only once)");
            return false;
        }
        return true;
    }

    bool parse_error(std::size_t position, const std::string& last_token, const json::exception& ex) override {
        if (ex.id == 406) {  // out_of_range.406: a number that does not fit a double
            error.emplace(nextPath(), "must be a finite number (got " + last_token + ", too large for a double)");
            return false;
        }
        // "[json.exception.parse_error.101] parse error at line 2, column 5: syntax error ..."
        std::string message = ex.what();
        if (const auto bracket = message.find("] "); bracket != std::string::npos) message.erase(0, bracket + 2);
        const std::string prefix = "parse error at ";
        const auto colon = message.find(": ");
        if (message.rfind(prefix, 0) == 0 && colon != std::string::npos) {
            message = "invalid JSON at " + message.substr(prefix.size(), colon - prefix.size()) + " (byte " +
                      std::to_string(position) + "): " + message.substr(colon + 2);
        } else {
            message = "invalid JSON at byte " + std::to_string(position) + ": " + message;
        }
        error.emplace("", message);
        return false;
    }

private:
    struct Frame {
        json* value;      ///< the open object or array
        std::string path; ///< its path
        std::string key;  ///< object: the key of the value being read
    };
    std::vector<Frame> stack_;
    static constexpr std::size_t kMaxDepth = 64;

    /// The path of the value about to be read.
    std::string nextPath() const {
        if (stack_.empty()) return "";
        const Frame& f = stack_.back();
        return f.value->is_array() ? elementPath(f.path, f.value->size()) : memberPath(f.path, f.key);
    }

    /// Stores `v` where the next value goes and returns where it went.
    json* place(json&& v) {
        if (stack_.empty()) {
            root = std::move(v);
            return &root;
        }
        Frame& f = stack_.back();
        if (f.value->is_array()) {
            f.value->push_back(std::move(v));
            return &f.value->back();
        }
        json& slot = (*f.value)[f.key];
        slot = std::move(v);
        return &slot;
    }

    bool add(json v) {
        place(std::move(v));
        return true;
    }
    bool open(json v) {
        // Every open level keeps its path, so deep nesting costs O(depth^2) time and memory
        // (the fuzz regression test's 100000 nested arrays); a scene nests a handful.
        if (stack_.size() >= kMaxDepth) {
            error.emplace(nextPath(), "nested deeper than " + std::to_string(kMaxDepth) + " levels");
            return false;
        }
        std::string path = nextPath();
        json* where = place(std::move(v));
        stack_.push_back({where, std::move(path), {}});
        return true;
    }
    bool close() {
        stack_.pop_back();
        return true;
    }
};

/// Parses JSON text with // and /* */ comments allowed. Throws InvalidInput.
json parseJson(const std::string& text) {
    PathTrackingBuilder builder;
    bool ok = false;
    try {
        ok = json::sax_parse(text, &builder, json::input_format_t::json, /*strict=*/true, /*ignore_comments=*/true);
    } catch (const json::exception& e) {
        throw InvalidInput("", std::string("invalid JSON: ") + e.what());
    }
    if (builder.error) throw *builder.error;
    if (!ok) throw InvalidInput("", "invalid JSON");
    return std::move(builder.root);
}

// =============================================================================================
// Number ranges
// =============================================================================================

/// An interval of accepted values for a number field, with the text for its error message.
struct Range {
    double lo = -std::numeric_limits<double>::infinity();
    double hi = std::numeric_limits<double>::infinity();
    bool lo_open = false;
    bool hi_open = false;

    static Range any() { return {}; }
    static Range positive() { return {0.0, std::numeric_limits<double>::infinity(), true, false}; }
    static Range atLeast(double lo) { return {lo, std::numeric_limits<double>::infinity(), false, false}; }
    static Range closed(double lo, double hi) { return {lo, hi, false, false}; }
    static Range leftOpen(double lo, double hi) { return {lo, hi, true, false}; }
    /// Positions, offsets and velocities that Bullet stores in single precision: within
    /// +-1e6 (m, m/s, rad/s, m/s^2), where a float still resolves them.
    static Range bullet() { return closed(-kMaxPosition, kMaxPosition); }

    bool contains(double v) const {
        return std::isfinite(v) && (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
    }
    /// "greater than 0", "at least 0", "in (0, 0.1]", ...
    std::string text() const {
        const bool has_lo = std::isfinite(lo), has_hi = std::isfinite(hi);
        if (has_lo && has_hi)
            return std::string("in ") + (lo_open ? "(" : "[") + formatNumber(lo) + ", " + formatNumber(hi) +
                   (hi_open ? ")" : "]");
        if (has_lo) return (lo_open ? "greater than " : "at least ") + formatNumber(lo);
        if (has_hi) return (hi_open ? "less than " : "at most ") + formatNumber(hi);
        return "a finite number";
    }
};

/// "in [1, 8]" for an integer range; "at least 0" / "at most 9" when the other side is open
/// (LLONG_MIN, LLONG_MAX) and the value is `below` / above the range.
std::string integerRangeText(long long lo, long long hi, bool below) {
    if (lo == LLONG_MIN || hi == LLONG_MAX) return below ? "at least " + std::to_string(lo) : "at most " + std::to_string(hi);
    return "in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
}

// =============================================================================================
// Node: a JSON value and its path, with checked accessors
// =============================================================================================

/// A JSON value of the scene together with its path. Its accessors check the value and throw
/// InvalidInput naming the path of the offending field. The referenced JSON must outlive it.
class Node {
public:
    Node(const json& value, std::string path) : value_(&value), path_(std::move(path)) {}

    const json& value() const { return *value_; }
    const std::string& path() const { return path_; }

    /// Throws InvalidInput(path, problem).
    [[noreturn]] void fail(const std::string& problem) const { throw InvalidInput(path_, problem); }

    // --- this value, checked ------------------------------------------------------------------

    const Node& expectObject() const {
        if (!value_->is_object()) fail("expected an object, got " + describe(*value_));
        return *this;
    }

    /// The elements of this array.
    std::vector<Node> asArray() const {
        if (!value_->is_array()) fail("expected an array, got " + describe(*value_));
        std::vector<Node> out;
        out.reserve(value_->size());
        for (std::size_t i = 0; i < value_->size(); ++i) out.emplace_back((*value_)[i], elementPath(path_, i));
        return out;
    }

    /// The members of this object, in key order.
    std::vector<std::pair<std::string, Node>> members() const {
        expectObject();
        std::vector<std::pair<std::string, Node>> out;
        for (const auto& [key, v] : value_->items()) out.emplace_back(key, Node(v, memberPath(path_, key)));
        return out;
    }

    double asNumber(const Range& range = Range::any()) const {
        if (!value_->is_number()) fail("expected a number, got " + describe(*value_));
        const double v = value_->get<double>();
        if (!range.contains(v)) fail("must be " + range.text() + " (got " + gotText() + ")");
        return v;
    }

    /// A whole number in [lo, hi]; 3.0 is accepted, 2.5 is not.
    long long asInteger(long long lo = LLONG_MIN, long long hi = LLONG_MAX) const {
        if (!value_->is_number()) fail("expected an integer, got " + describe(*value_));
        long long v = 0;
        bool in_range = true;
        if (value_->is_number_unsigned()) {
            const auto u = value_->get<std::uint64_t>();
            in_range = u <= static_cast<std::uint64_t>(LLONG_MAX);
            v = in_range ? static_cast<long long>(u) : LLONG_MAX;
        } else if (value_->is_number_integer()) {
            v = value_->get<std::int64_t>();
        } else {
            const double d = value_->get<double>();
            if (std::floor(d) != d) fail("must be a whole number (got " + gotText() + ")");
            in_range = std::fabs(d) <= 9007199254740992.0;  // 2^53: exact as a double
            v = in_range ? static_cast<long long>(d) : 0;
        }
        if (!in_range || v < lo || v > hi) {
            const bool below = in_range ? v < lo : value_->get<double>() < 0.0;
            fail("must be " + integerRangeText(lo, hi, below) + " (got " + gotText() + ")");
        }
        return v;
    }

    bool asBool() const {
        if (!value_->is_boolean()) fail("expected a boolean (true or false), got " + describe(*value_));
        return value_->get<bool>();
    }

    std::string asString() const {
        if (!value_->is_string()) fail("expected a string, got " + describe(*value_));
        return value_->get<std::string>();
    }

    /// An array of exactly `count` numbers, each in `range` (errors name the element: box[1]).
    std::vector<double> asNumbers(std::size_t count, const Range& range = Range::any()) const {
        if (!value_->is_array() || value_->size() != count)
            fail("expected an array of " + std::to_string(count) + " numbers, got " + describe(*value_));
        std::vector<double> out;
        for (const Node& e : asArray()) out.push_back(e.asNumber(range));
        return out;
    }

    /// A positive number (a size, a mass) of at most `max`: "greater than 0" below, the
    /// whole range above.
    double asPositiveAtMost(double max) const {
        const double v = asNumber(Range::positive());
        if (v > max) fail("must be " + Range::leftOpen(0.0, max).text() + " (got " + gotText() + ")");
        return v;
    }
    /// A size of a body's shape: in [kMinSize, kMaxSize] m.
    double asSize() const { return asNumber(Range::closed(kMinSize, kMaxSize)); }
    Vec3 asVec3(const Range& range = Range::any()) const {
        const std::vector<double> v = asNumbers(3, range);
        return {v[0], v[1], v[2]};
    }

    /// A vector of finite components whose length is at most `max` (a speed, a force).
    Vec3 asVec3AtMost(double max, const char* unit) const {
        const Vec3 v = asVec3();
        const double length = v.stableNorm();  // no overflow for components up to DBL_MAX
        if (!(length <= max)) fail("its length must be at most " + formatNumber(max) + " " + unit + " (got " + formatNumber(length) + ")");
        return v;
    }

    /// A rotation written [x, y, z, w]; normalised. Its norm, taken without overflow or
    /// underflow (scaled by the largest component), must be in [kMinNorm, kMaxNorm].
    Quat asQuaternion() const {
        const std::vector<double> v = asNumbers(4);
        const double scale = std::max({std::fabs(v[0]), std::fabs(v[1]), std::fabs(v[2]), std::fabs(v[3])});
        const double norm = scale > 0.0 ? scale * Eigen::Vector4d(v[0] / scale, v[1] / scale, v[2] / scale, v[3] / scale).norm() : 0.0;
        if (!(norm >= kMinNorm && norm <= kMaxNorm))
            fail("must be a quaternion [x, y, z, w] of norm in [" + formatNumber(kMinNorm) + ", " + formatNumber(kMaxNorm) +
                 "] (got norm " + formatNumber(norm) + ")");
        return Quat(v[3] / norm, v[0] / norm, v[1] / norm, v[2] / norm);
    }

    // --- fields of this object ----------------------------------------------------------------

    /// The field `key`, or nullopt when absent.
    std::optional<Node> field(const std::string& key) const {
        expectObject();
        const auto it = value_->find(key);
        if (it == value_->end()) return std::nullopt;
        return Node(*it, memberPath(path_, key));
    }

    bool has(const std::string& key) const { return field(key).has_value(); }

    /// The field `key`; throws "missing required field" at its path when absent.
    Node required(const std::string& key) const {
        if (auto f = field(key)) return *f;
        throw InvalidInput(memberPath(path_, key), "missing required field");
    }

    /// Requires an object whose fields are all among `allowed`; an unknown one is reported at its path.
    void checkNoUnknownFields(const std::vector<const char*>& allowed) const {
        for (const auto& member : members()) {
            const auto is_key = [&](const char* a) { return member.first == a; };
            if (std::none_of(allowed.begin(), allowed.end(), is_key))
                member.second.fail("unknown field (allowed: " + joinNames(allowed) + ")");
        }
    }

    double number(const std::string& key, double fallback, const Range& range = Range::any()) const {
        const auto f = field(key);
        return f ? f->asNumber(range) : fallback;
    }
    long long integer(const std::string& key, long long fallback, long long lo, long long hi) const {
        const auto f = field(key);
        return f ? f->asInteger(lo, hi) : fallback;
    }
    bool boolean(const std::string& key, bool fallback) const {
        const auto f = field(key);
        return f ? f->asBool() : fallback;
    }
    Vec3 vec3(const std::string& key, const Vec3& fallback, const Range& range = Range::any()) const {
        const auto f = field(key);
        return f ? f->asVec3(range) : fallback;
    }
    /// The elements of the array field `key`; none when absent.
    std::vector<Node> array(const std::string& key) const {
        const auto f = field(key);
        return f ? f->asArray() : std::vector<Node>{};
    }

private:
    /// The value as the user wrote it (numbers), for "(got ...)".
    std::string gotText() const { return value_->dump(-1, ' ', false, json::error_handler_t::replace); }

    const json* value_;
    std::string path_;
};

// =============================================================================================
// Shared field readers
// =============================================================================================

/// The words of a sheet or cloth that meant something else before (docs/SCENE_FORMAT.md,
/// "Words"): each is refused with what to write now.
void refuseOldSheetWords(const Node& n, bool paper) {
    if (const auto origin = n.field("origin")) {
        const std::string v = origin->value().dump();
        origin->fail(paper ? "is not a word for sheets: a paper's origin was its centre; write \"center\": " + v +
                                 " (or \"corner\" for where vertex [0, 0] lies)"
                           : "is not a word for sheets: a cloth's origin was its corner, vertex [0, 0]; write \"corner\": " + v +
                                 " (or \"center\" for its centre)");
    }
    if (paper)
        if (const auto density = n.field("density"))
            density->fail("is kg/m^3 of material (a string's, a cloth's yarn fibre); a sheet's mass per area is areal_density, "
                          "kg/m^2: write \"areal_density\": " + density->value().dump());
}

/// Where a rectangular sheet or cloth lies: "center" or "corner" (not both; neither: its
/// centre at defaultSheetCenter()). Every vertex lies within `diagonal` of its corner
/// and half of it of its centre, in any orientation: all must stay within the position bound.
void parsePlacement(const Node& n, std::optional<Vec3>& center, std::optional<Vec3>& corner, double diagonal) {
    const auto c = n.field("center");
    const auto k = n.field("corner");
    if (c && k) k->fail("give center or corner, not both");
    if (c) center = c->asVec3(Range::bullet());
    if (k) corner = k->asVec3(Range::bullet());
    const Vec3 anchor = corner ? *corner : center.value_or(defaultSheetCenter());
    const double reach = anchor.cwiseAbs().maxCoeff() + (corner ? diagonal : 0.5 * diagonal);
    if (reach <= kMaxPosition) return;
    const auto size = n.field("size");
    (size ? *size : k ? *k : n.required("center"))
        .fail("its corners may reach " + formatNumber(reach) +
              " m from the world's origin along an axis (the largest coordinate of its " + (corner ? "corner" : "centre") +
              " plus the farthest a vertex lies from it), past the position bound of " + formatNumber(kMaxPosition) + " m");
}

/// A vertex of a rectangular grid of nx x nz vertices (a paper sheet's or a cloth's; the
/// same words for both): a flat index k * nx + i, or [i, k] with i along local x and k
/// along local z; each negative counts from the end. Returns the flat index.
std::uint32_t gridVertexIndex(const Node& n, long long nx, long long nz, const char* what) {
    const long long count = nx * nz;
    if (n.value().is_array()) {
        if (n.value().size() != 2) n.fail("expected a vertex index or [i, k] (2 integers), got " + describe(n.value()));
        const std::vector<Node> ik = n.asArray();
        long long out[2];
        for (int a = 0; a < 2; ++a) {
            const long long v = ik[a].asInteger();
            const long long along = a == 0 ? nx : nz;
            if (v < -along || v >= along)
                ik[a].fail("vertex index out of range (got " + std::to_string(v) + "; the " + what + " has " + std::to_string(along) +
                           " vertices along this axis)");
            out[a] = v < 0 ? v + along : v;
        }
        return static_cast<std::uint32_t>(out[1] * nx + out[0]);
    }
    if (!n.value().is_number()) n.fail("expected a vertex index or [i, k] (2 integers), got " + describe(n.value()));
    const long long v = n.asInteger();
    if (v < -count || v >= count)
        n.fail("vertex index out of range (got " + std::to_string(v) + "; the " + what + " has " + std::to_string(count) +
               " vertices: 0.." + std::to_string(count - 1) + ", or -" + std::to_string(count) + "..-1 from the end)");
    return static_cast<std::uint32_t>(v < 0 ? v + count : v);
}

/// The vertices of a side of a rectangular grid: "x-", "x+", "z-" or "z+" (the side at the
/// low or high end of that local axis), in order along it.
std::vector<std::uint32_t> gridEdge(const Node& n, int nx, int nz) {
    const std::string e = n.asString();
    std::vector<std::uint32_t> out;
    if (e == "x-" || e == "x+") {
        for (int k = 0; k < nz; ++k) out.push_back(static_cast<std::uint32_t>(k * nx + (e == "x-" ? 0 : nx - 1)));
    } else if (e == "z-" || e == "z+") {
        for (int i = 0; i < nx; ++i) out.push_back(static_cast<std::uint32_t>((e == "z-" ? 0 : nz - 1) * nx + i));
    } else {
        n.fail("must be \"x-\", \"x+\", \"z-\" or \"z+\" (got " + jsonQuoted(e) + ")");
    }
    return out;
}

/// The required, non-empty "name" field.
std::string requiredName(const Node& n) {
    const Node field = n.required("name");
    std::string name = field.asString();
    if (name.empty()) field.fail("must not be empty");
    return name;
}

/// Records `name` (of the object at `owner`) as taken; throws at `owner.name` if it already is.
void claimName(NameMap& names, const std::string& name, const std::string& owner, const std::string& what) {
    const auto [it, fresh] = names.emplace(name, owner);
    if (!fresh)
        throw InvalidInput(memberPath(owner, "name"),
                           "duplicate " + what + " name " + jsonQuoted(name) + " (also used by " + it->second + ")");
}

std::vector<std::string> namesOf(const NameMap& names) {
    std::vector<std::string> out;
    for (const auto& entry : names) out.push_back(entry.first);
    return out;
}

/// Resolves particle index `i` of a string with `count` particles (negative counts from the
/// end) to [0, count); throws at `where` when it is out of range.
int resolveParticle(const Node& where, long long i, long long count) {
    if (i < -count || i >= count)
        where.fail("particle index out of range (got " + std::to_string(i) + "; the string has " + std::to_string(count) +
                   " particles: 0.." + std::to_string(count - 1) + ", or -" + std::to_string(count) + "..-1 from the end)");
    return static_cast<int>(i < 0 ? i + count : i);
}

/// The particle index held by `n`, resolved to [0, count).
int particleIndex(const Node& n, long long count) { return resolveParticle(n, n.asInteger(), count); }

// =============================================================================================
// Bodies
// =============================================================================================

Shape parseShape(const Node& n) {
    n.checkNoUnknownFields({"box", "sphere", "capsule", "plane"});
    if (n.value().size() != 1) {
        std::vector<std::string> given;
        for (const auto& member : n.members()) given.push_back(member.first);
        n.fail("needs exactly one of box, sphere, capsule, plane (got " + (given.empty() ? "none" : joinNames(given)) + ")");
    }
    Shape s;
    if (const auto box = n.field("box")) {
        s.kind = Shape::Kind::Box;
        box->asNumbers(3);
        const std::vector<Node> h = box->asArray();
        s.half_extents = {h[0].asSize(), h[1].asSize(), h[2].asSize()};
    } else if (const auto sphere = n.field("sphere")) {
        s.kind = Shape::Kind::Sphere;
        s.radius = sphere->asSize();
    } else if (const auto capsule = n.field("capsule")) {
        s.kind = Shape::Kind::Capsule;
        capsule->asNumbers(2);
        const std::vector<Node> c = capsule->asArray();
        s.radius = c[0].asSize();
        s.half_height = c[1].asSize();
    } else {
        const Node plane = n.required("plane");
        s.kind = Shape::Kind::Plane;
        const std::vector<double> p = plane.asNumbers(4, Range::bullet());
        const Vec3 normal(p[0], p[1], p[2]);
        const double length = normal.norm();
        if (!(length >= kMinNorm))
            plane.fail("the normal [nx, ny, nz] must have a length of at least " + formatNumber(kMinNorm) + " (got " +
                       formatNumber(length) + ")");
        // n . x = d with n as written: scale both so that the normal is a unit vector.
        s.plane_normal = normal / length;
        s.plane_offset = p[3] / length;
        if (!(std::fabs(s.plane_offset) <= kMaxPosition))
            plane.fail("the offset d / |n| must be in [-1e+06, 1e+06] m (got " + formatNumber(s.plane_offset) + ")");
    }
    return s;
}

/// A rigid body (in bodies[] or a spawn driver). Its name's uniqueness is checked by the caller.
Body parseBody(const Node& n) {
    n.checkNoUnknownFields({"name", "shape", "mass", "kinematic", "position", "orientation", "linear_velocity",
                            "angular_velocity", "friction", "restitution"});
    Body b;
    b.name = requiredName(n);
    b.shape = parseShape(n.required("shape"));
    const bool plane = b.shape.kind == Shape::Kind::Plane;
    b.mass = n.number("mass", plane ? 0.0 : b.mass, Range::atLeast(0.0));
    if (b.mass != 0.0 && !(b.mass >= kMinBodyMass && b.mass <= kMaxBodyMass))
        n.required("mass").fail("must be 0 (static) or in [" + formatNumber(kMinBodyMass) + ", " + formatNumber(kMaxBodyMass) +
                                "] kg (got " + formatNumber(b.mass) + ")");
    if (plane && b.mass != 0.0)
        n.required("mass").fail("a plane must be static: mass 0 (got " + formatNumber(b.mass) + ")");
    b.kinematic = n.boolean("kinematic", b.kinematic);
    if (plane && b.kinematic) n.required("kinematic").fail("a plane cannot be kinematic (it is static)");
    b.position = n.vec3("position", b.position, Range::bullet());
    if (const auto q = n.field("orientation")) b.orientation = q->asQuaternion();
    if (const auto v = n.field("linear_velocity")) b.linear_velocity = v->asVec3AtMost(kMaxSpeed, "m/s");
    b.angular_velocity = n.vec3("angular_velocity", b.angular_velocity, Range::bullet());
    b.friction = n.number("friction", b.friction, Range::closed(0.0, 1e3));
    b.restitution = n.number("restitution", b.restitution, Range::closed(0.0, 1.0));
    return b;
}

// =============================================================================================
// Joints
// =============================================================================================

constexpr double kPi = 3.14159265358979323846;

/// A joint (joints[]) between the scene's `bodies` (`names`: their names).
Joint parseJoint(const Node& n, const NameMap& names, const std::vector<Body>& bodies) {
    n.checkNoUnknownFields({"type", "body", "other", "pivot", "axis", "limits", "motor", "stiffness", "damping"});
    Joint j;
    const Node type = n.required("type");
    const std::string kind = type.asString();
    if (kind == "ball") {
        j.kind = Joint::Kind::Ball;
    } else if (kind == "hinge") {
        j.kind = Joint::Kind::Hinge;
    } else if (kind == "slider") {
        j.kind = Joint::Kind::Slider;
    } else if (kind == "fixed") {
        j.kind = Joint::Kind::Fixed;
    } else if (kind == "spring") {
        j.kind = Joint::Kind::Spring;
    } else {
        type.fail("must be \"ball\", \"hinge\", \"slider\", \"fixed\" or \"spring\" (got " + jsonQuoted(kind) + ")");
    }
    auto body = [&](const Node& field) -> const Body& {
        const std::string name = field.asString();
        for (const Body& b : bodies)
            if (b.name == name) return b;
        field.fail("no body named " + jsonQuoted(name) + knownNames(namesOf(names), "bodies"));
    };
    const Node body_field = n.required("body");
    const Body& a = body(body_field);
    if (a.mass == 0.0 || a.kinematic)
        body_field.fail("must name a dynamic body (mass > 0, not kinematic): \"" + a.name + "\" is " +
                        (a.kinematic ? "kinematic" : "static") + " (give it as \"other\", or leave \"other\" out for the world)");
    j.body = a.name;
    if (const auto other = n.field("other")) {
        const Body& b = body(*other);
        if (b.name == a.name) other->fail("must name another body than \"body\" (got " + jsonQuoted(b.name) + ")");
        j.other = b.name;
    }
    j.pivot = n.required("pivot").asVec3(Range::bullet());
    const bool linear = j.kind == Joint::Kind::Slider || j.kind == Joint::Kind::Spring;
    const char* what = j.kind == Joint::Kind::Ball     ? "a ball joint"
                       : j.kind == Joint::Kind::Fixed  ? "a fixed joint"
                       : j.kind == Joint::Kind::Slider ? "a slider"
                       : j.kind == Joint::Kind::Spring ? "a spring"
                                                       : "a hinge";
    if (j.kind == Joint::Kind::Ball || j.kind == Joint::Kind::Fixed) {
        for (const char* key : {"axis", "limits"})
            if (const auto extra = n.field(key)) extra->fail(std::string("is for hinges, sliders and springs only (this joint is ") + what + ")");
    }
    if (j.kind != Joint::Kind::Hinge && j.kind != Joint::Kind::Slider)
        if (const auto extra = n.field("motor")) extra->fail(std::string("is for hinges and sliders only (this joint is ") + what + ")");
    if (j.kind != Joint::Kind::Spring) {
        for (const char* key : {"stiffness", "damping"})
            if (const auto extra = n.field(key)) extra->fail(std::string("is for springs only (this joint is ") + what + ")");
    }
    if (j.kind == Joint::Kind::Ball || j.kind == Joint::Kind::Fixed) return j;
    const Node axis = n.required("axis");
    j.axis = axis.asVec3(Range::bullet());
    const double length = j.axis.stableNorm();
    if (!(length > 1e-9))
        axis.fail(j.kind == Joint::Kind::Hinge ? "must not be zero (a hinge turns about it)" : std::string("must not be zero (") + what + " moves along it)");
    j.axis /= length;
    if (j.kind == Joint::Kind::Spring) {
        j.stiffness = n.required("stiffness").asNumber(Range{0.0, 1e9, true, false});
        j.damping = n.number("damping", 0.0, Range::closed(0.0, 1e9));
    }
    if (const auto limits = n.field("limits")) {
        const std::vector<double> v = limits->asNumbers(2, linear ? Range::bullet() : Range::closed(-kPi, kPi));
        if (!(v[0] <= v[1])) limits->fail("must be [lower, upper] with lower <= upper (got [" + formatNumber(v[0]) + ", " + formatNumber(v[1]) + "])");
        j.limits = std::array<double, 2>{v[0], v[1]};
    }
    if (const auto motor = n.field("motor")) {
        // A hinge's motor gives way past an impulse a step (btHingeConstraint), a slider's
        // past a force (btSliderConstraint).
        const bool slider = j.kind == Joint::Kind::Slider;
        motor->checkNoUnknownFields({"velocity", slider ? "force" : "impulse"});
        Joint::Motor m;
        m.velocity = motor->required("velocity").asNumber(Range::closed(-1e3, 1e3));
        (slider ? m.force : m.impulse) = motor->required(slider ? "force" : "impulse").asNumber(Range{0.0, 1e6, true, false});
        j.motor = m;
    }
    return j;
}

// =============================================================================================
// Strings
// =============================================================================================

/// The particle rest positions: "points", or "from", "to" and "segments".
std::vector<Vec3> parseGeometry(const Node& n) {
    if (const auto points = n.field("points")) {
        for (const char* key : {"from", "to", "segments"})
            if (const auto extra = n.field(key))
                extra->fail("not allowed together with points (give either points, or from, to and segments)");
        const std::vector<Node> list = points->asArray();
        if (list.size() < 2) points->fail("a string needs at least 2 points (got " + std::to_string(list.size()) + ")");
        std::vector<Vec3> out;
        out.reserve(list.size());
        for (const Node& p : list) out.push_back(p.asVec3(Range::bullet()));
        return out;  // zero-length segments: validate() reports points[i]
    }
    if (!n.has("from") && !n.has("to") && !n.has("segments"))
        n.fail("needs its geometry: points, or from, to and segments");
    const Vec3 from = n.required("from").asVec3(Range::bullet());
    const Node to_node = n.required("to");
    const Vec3 to = to_node.asVec3(Range::bullet());
    const long long segments = n.integer("segments", 10, 1, 1'000'000);
    const double length = (to - from).norm();
    if (!(length > 1e-9)) to_node.fail("must differ from from (the string would have zero length)");
    if (!(length / static_cast<double>(segments) > 1e-9))
        to_node.fail("is too close to from for " + std::to_string(segments) + " segments (each would be shorter than 1e-9 m)");
    return StringDesc::straight(from, to, static_cast<int>(segments)).points;
}

/// {"index": mass, ...}: keys are particle indices as strings, negative from the end.
std::vector<std::pair<int, double>> parseParticleMasses(const Node& n, long long particles) {
    std::vector<std::pair<int, double>> out;
    std::map<int, std::string> seen;  // resolved index -> key path
    for (const auto& [key, value] : n.members()) {
        const std::size_t digits = key.size() - (key.rfind('-', 0) == 0 ? 1 : 0);
        const bool integer = digits >= 1 && digits <= 10 &&
                             std::all_of(key.end() - static_cast<std::ptrdiff_t>(digits), key.end(),
                                         [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
        if (!integer) value.fail("the key must be a particle index such as \"0\" or \"-1\" (got " + jsonQuoted(key) + ")");
        const long long index = std::stoll(key);
        const int resolved = resolveParticle(value, index, particles);
        const auto [it, fresh] = seen.emplace(resolved, value.path());
        if (!fresh) value.fail("particle " + std::to_string(resolved) + " already has a mass (" + it->second + ")");
        out.emplace_back(static_cast<int>(index), value.asPositiveAtMost(1e12));  // kg, as validate(StringDesc)
    }
    return out;
}

void parseMaterial(const Node& n, Material& m) {
    n.checkNoUnknownFields({"preset", "tensile", "torsion", "variation"});
    // A named preset first (presets.hpp); the fields below override parts of it.
    if (const auto p = n.field("preset")) {
        const std::string name = p->asString();
        try {
            m = materialPreset(name);  // the lookup C++ programs use too
        } catch (const InvalidInput& e) {
            p->fail(e.problem());
        }
    }
    if (const auto t = n.field("tensile")) {
        t->checkNoUnknownFields({"young", "yield", "plastic_modulus", "rupture"});
        TensileCurve& c = m.tensile;
        c.young = t->number("young", c.young, Range::positive());
        c.yield = t->number("yield", c.yield, Range::positive());
        c.plastic_modulus = t->number("plastic_modulus", c.plastic_modulus, Range::positive());
        c.rupture = t->number("rupture", c.rupture, Range::positive());  // > yield: validate()
    }
    if (const auto t = n.field("torsion")) {
        t->checkNoUnknownFields({"modulus", "yield", "plastic_modulus", "rupture"});
        TorsionCurve& c = m.torsion;
        c.modulus = t->number("modulus", c.modulus, Range::positive());
        c.yield = t->number("yield", c.yield, Range::positive());
        c.plastic_modulus = t->number("plastic_modulus", c.plastic_modulus, Range::positive());
        c.rupture = t->number("rupture", c.rupture, Range::positive());  // > yield: validate()
    }
    m.variation = n.number("variation", m.variation, Range::closed(0.0, 0.5));
}

/// One half-width for all segments, or an array with one per segment.
std::vector<int> parseTwistHalfWidth(const Node& n, std::size_t segments) {
    if (n.value().is_number()) return {static_cast<int>(n.asInteger(1, 8))};
    if (!n.value().is_array())
        n.fail("expected an integer or an array of integers (one per segment), got " + describe(n.value()));
    const std::vector<Node> list = n.asArray();
    if (list.size() != segments)
        n.fail("needs one value per segment (" + std::to_string(segments) + "), got " + std::to_string(list.size()));
    std::vector<int> out;
    for (const Node& e : list) out.push_back(static_cast<int>(e.asInteger(1, 8)));
    return out;
}

TensionEstimator parseTension(const Node& n) {
    const std::string v = n.asString();
    if (v == "momentum") return TensionEstimator::Momentum;
    if (v == "local") return TensionEstimator::Local;
    n.fail("must be \"momentum\" or \"local\" (got " + jsonQuoted(v) + ")");
}

StringIntegrator parseIntegrator(const Node& n) {
    const std::string v = n.asString();
    if (v == "backward_euler") return StringIntegrator::BackwardEuler;
    if (v == "bdf2") return StringIntegrator::BDF2;
    n.fail("must be \"backward_euler\" or \"bdf2\" (got " + jsonQuoted(v) + ")");
}

/// A string's "attachments", with a sheet's words (parseSheetAttachments): {"particle": an
/// index; "body": a name, with "local": a point in its frame (default: where the particle
/// is) | "world": true (where the particle is) or a point}.
std::vector<Attachment> parseAttachments(const Node& list, const std::vector<Vec3>& points, const NameMap& bodies) {
    const auto particles = static_cast<long long>(points.size());
    std::vector<Attachment> out;
    std::map<int, std::string> taken;  // resolved particle -> attachment path
    for (const Node& n : list.asArray()) {
        n.checkNoUnknownFields({"particle", "body", "local", "world"});
        Attachment a;
        const Node particle = n.required("particle");
        a.particle = particleIndex(particle, particles);
        if (const auto [it, fresh] = taken.emplace(a.particle, n.path()); !fresh)
            particle.fail("particle " + std::to_string(a.particle) + " already has an attachment (" + it->second + ")");
        const auto body = n.field("body");
        const auto world = n.field("world");
        const auto local = n.field("local");
        if (body && world) world->fail("give either body or world, not both");
        if (!body && !world) n.fail("needs body (a body's name) or world (true: where the particle is, or a point)");
        if (body) {
            a.body = body->asString();
            if (bodies.count(*a.body) == 0) body->fail("no body named " + jsonQuoted(*a.body) + knownNames(namesOf(bodies), "bodies"));
            if (local) a.local = local->asVec3(Range::bullet());
        } else {
            if (local) local->fail("only allowed with body");
            if (world->value().is_boolean()) {
                if (!world->asBool()) world->fail("false attaches nothing: give true (where the particle is) or a point");
                a.world = points[static_cast<std::size_t>(a.particle)];
            } else {
                a.world = world->asVec3(Range::bullet());
            }
        }
        out.push_back(std::move(a));
    }
    return out;
}

/// Bullet's collision filter of a string, sheet or cloth: 32-bit group and mask, each as a
/// signed or an unsigned number (-1 and 4294967295 are the same mask).
template <class Object>
void parseFilter(const Node& n, Object& object) {
    const auto bits = [&](const char* key, int fallback) {
        return static_cast<int>(static_cast<std::uint32_t>(n.integer(key, fallback, INT32_MIN, UINT32_MAX)));
    };
    object.collision_group = bits("collision_group", object.collision_group);
    object.collision_mask = bits("collision_mask", object.collision_mask);
}

/// A string; `seed` is its material variation seed, `bodies` the bodies it may attach to.
String parseString(const Node& n, std::uint64_t seed, const NameMap& bodies) {
    n.checkNoUnknownFields({"name", "points", "from", "to", "segments", "radius", "density", "particle_masses",
                            "material", "csm_half_width", "twist_half_width", "tension", "integrator", "tearable",
                            "yield_in_solve", "damping", "axial_damping", "bending", "attachments", "collision_group",
                            "collision_mask"});
    String s;
    StringDesc& d = s.desc;
    d.name = requiredName(n);
    d.points = parseGeometry(n);
    s.geometry_field = n.has("points") ? "points" : "segments";
    const auto particles = static_cast<long long>(d.points.size());
    d.radius = n.number("radius", d.radius, Range::positive());
    d.density = n.number("density", d.density, Range::positive());
    if (const auto m = n.field("particle_masses")) d.particle_masses = parseParticleMasses(*m, particles);
    if (const auto m = n.field("material")) parseMaterial(*m, d.material);
    d.csm_half_width = static_cast<int>(n.integer("csm_half_width", d.csm_half_width, 1, 8));
    if (const auto t = n.field("twist_half_width")) d.twist_half_width = parseTwistHalfWidth(*t, d.points.size() - 1);
    if (const auto t = n.field("tension")) d.tension = parseTension(*t);
    if (const auto t = n.field("integrator")) d.integrator = parseIntegrator(*t);
    d.tearable = n.boolean("tearable", d.tearable);
    d.yield_in_solve = n.boolean("yield_in_solve", d.yield_in_solve);
    d.damping = n.number("damping", d.damping, Range::atLeast(0.0));
    d.axial_damping = n.number("axial_damping", d.axial_damping, Range::closed(0.0, 1.0));
    d.bending = n.number("bending", d.bending, Range::closed(0.0, 1.0));
    d.seed = seed;
    try {
        validate(d);  // what the fields above cannot check alone: rupture > yield, zero-length segments, ...
    } catch (const InvalidInput& e) {
        throw InvalidInput(e.field().empty() ? n.path() : n.path() + "." + e.field(), e.problem());
    }
    if (const auto a = n.field("attachments")) s.attachments = parseAttachments(*a, d.points, bodies);
    parseFilter(n, s);
    return s;
}

// =============================================================================================
// Sheets and cloths: the same words for both
// =============================================================================================

/// A vertex of a paper sheet or cloth: gridVertexIndex on a rectangle; on a mesh (`grid`
/// false, `vertices` of them) only a flat index.
std::uint32_t sheetVertex(const Node& n, bool grid, int nx, int nz, std::size_t vertices, const char* what) {
    if (!grid) {
        if (n.value().is_array()) n.fail("[i, k] names a grid vertex: this sheet is a mesh, give an index");
        return gridVertexIndex(n, static_cast<long long>(vertices), 1, what);
    }
    return gridVertexIndex(n, nx, nz, what);
}

/// What holds a vertex of a sheet or cloth at creation.
struct SheetHold {
    std::uint32_t vertex = 0;         ///< flat index
    std::optional<std::string> body;  ///< glued to this body, or (none) pinned in the world
    std::optional<Vec3> local;        ///< with body: the point in its frame, m; default: where the vertex is
    std::optional<Vec3> world;        ///< without body: the world point, m; default (true): where the vertex is
};

/// The "attachments" of a paper sheet or cloth, one per vertex: {"vertex": an index or
/// [i, k] | "edge": "x-", "x+", "z-" or "z+"; "body": a name, with "local": a point in its
/// frame | "world": true or a point}. `grid` is false for a sheet given as a mesh.
std::vector<SheetHold> parseSheetAttachments(const Node& list, bool grid, int nx, int nz, std::size_t vertices, const char* what,
                                             const NameMap& bodies) {
    std::vector<SheetHold> out;
    std::map<std::uint32_t, std::string> taken;  // vertex -> attachment path
    for (const Node& a : list.asArray()) {
        a.checkNoUnknownFields({"vertex", "edge", "world", "body", "local"});
        const auto vertex = a.field("vertex");
        const auto edge = a.field("edge");
        if (vertex && edge) edge->fail("give vertex or edge, not both");
        if (!vertex && !edge) a.fail("needs vertex (an index or [i, k]) or edge (\"x-\", \"x+\", \"z-\", \"z+\")");
        if (edge && !grid) edge->fail("edges are those of the rectangle: this sheet is a mesh");
        const std::vector<std::uint32_t> which =
            vertex ? std::vector<std::uint32_t>{sheetVertex(*vertex, grid, nx, nz, vertices, what)} : gridEdge(*edge, nx, nz);
        const auto body = a.field("body");
        const auto world = a.field("world");
        const auto local = a.field("local");
        if (body && world) world->fail("give either body or world, not both");
        if (!body && !world) a.fail("needs body (a body's name) or world (true: where the vertex is, or a point)");
        if (local && !body) local->fail("only allowed with body");
        if (local && edge) local->fail("an edge is glued where it is: give no local point");
        SheetHold h;
        if (body) {
            h.body = body->asString();
            if (bodies.count(*h.body) == 0) body->fail("no body named " + jsonQuoted(*h.body) + knownNames(namesOf(bodies), "bodies"));
            if (local) h.local = local->asVec3(Range::bullet());
        } else if (world->value().is_boolean()) {
            if (!world->asBool()) world->fail("false attaches nothing: give true (where the vertex is) or a point");
        } else {
            h.world = world->asVec3(Range::bullet());
        }
        for (std::uint32_t v : which) {
            if (const auto [it, fresh] = taken.emplace(v, a.path()); !fresh)
                (vertex ? *vertex : *edge).fail("vertex " + std::to_string(v) + " already has an attachment (" + it->second + ")");
            h.vertex = v;
            out.push_back(h);
        }
    }
    return out;
}

// =============================================================================================
// Cloths
// =============================================================================================

/// [i, j] of a cloth vertex given as an index or [i, j] (negative counts from the end), resolved.
std::pair<int, int> clothVertex(const Node& n, const ClothDesc& d) {
    const std::uint32_t v = gridVertexIndex(n, d.resolution[0], d.resolution[1], "cloth");
    return {static_cast<int>(v % static_cast<std::uint32_t>(d.resolution[0])), static_cast<int>(v / static_cast<std::uint32_t>(d.resolution[0]))};
}

/// A weak yarn of a cloth whose resolution is known: {"vertex": [i, j], "yarn": "warp" |
/// "weft", "strength": (0, 1]}, the yarn that starts at that vertex (duplicates are left to
/// validate(), which names the entry).
ClothWeakYarn parseWeakYarn(const Node& n, const ClothDesc& d) {
    n.checkNoUnknownFields({"vertex", "yarn", "strength"});
    ClothWeakYarn w;
    const Node vertex = n.required("vertex");
    const auto [i, j] = clothVertex(vertex, d);
    w.i = i;
    w.j = j;
    const Node yarn = n.required("yarn");
    const std::string kind = yarn.asString();
    if (kind == "warp") w.kind = YarnKind::Warp;
    else if (kind == "weft") w.kind = YarnKind::Weft;
    else yarn.fail("must be \"warp\" or \"weft\" (got " + jsonQuoted(kind) + ")");
    const bool pair = vertex.value().is_array();
    if (w.kind == YarnKind::Warp && w.i + 1 >= d.resolution[0])
        (pair ? vertex.asArray()[0] : vertex).fail("no warp yarn starts in the last column: a warp yarn joins [i, j] and [i + 1, j]");
    if (w.kind == YarnKind::Weft && w.j + 1 >= d.resolution[1])
        (pair ? vertex.asArray()[1] : vertex).fail("no weft yarn starts in the last row: a weft yarn joins [i, j] and [i, j + 1]");
    w.strength = n.required("strength").asNumber(Range::leftOpen(0.0, 1.0));
    return w;
}

/// A cloth; `seed` is its material variation seed, `bodies` the bodies it may attach to.
Cloth parseCloth(const Node& n, std::uint64_t seed, const NameMap& bodies) {
    refuseOldSheetWords(n, /*paper=*/false);
    n.checkNoUnknownFields({"name", "center", "corner", "size", "resolution", "orientation", "areal_density", "density",
                            "yarn_radius", "material", "lambda", "shear_stiffness", "bending_stiffness", "damping",
                            "plastic_time", "tearable", "weak_yarns", "attachments", "collision_group", "collision_mask"});
    Cloth c;
    ClothDesc& d = c.desc;
    d.name = requiredName(n);
    if (const auto size = n.field("size")) {
        const std::vector<double> v = size->asNumbers(2, Range::closed(0.0, 2.0 * kMaxPosition));
        d.size = {v[0], v[1]};
    }
    if (const auto res = n.field("resolution")) {
        if (!res->value().is_array() || res->value().size() != 2)
            res->fail("expected an array of 2 integers, got " + describe(res->value()));
        const std::vector<Node> r = res->asArray();
        d.resolution = {static_cast<int>(r[0].asInteger(1, 2000)), static_cast<int>(r[1].asInteger(1, 2000))};
    }
    if (const auto q = n.field("orientation")) d.orientation = q->asQuaternion();
    parsePlacement(n, d.center, d.corner, std::hypot(d.size[0], d.size[1]));
    // One of the two densities: giving density alone switches areal_density off.
    const bool has_density = n.has("density");
    d.areal_density = n.number("areal_density", has_density ? 0.0 : d.areal_density, Range::atLeast(0.0));
    d.density = n.number("density", d.density, Range::atLeast(0.0));
    d.yarn_radius = n.number("yarn_radius", d.yarn_radius, Range::positive());
    if (const auto m = n.field("material")) parseMaterial(*m, d.material);
    d.lambda = n.number("lambda", d.lambda, Range::closed(0.0, 1.0));
    d.shear_stiffness = n.number("shear_stiffness", d.shear_stiffness, Range::atLeast(0.0));
    d.bending_stiffness = n.number("bending_stiffness", d.bending_stiffness, Range::atLeast(0.0));
    d.damping = n.number("damping", d.damping, Range::closed(0.0, 1000.0));
    d.plastic_time = n.number("plastic_time", d.plastic_time, Range::closed(0.0, 10.0));
    d.tearable = n.boolean("tearable", d.tearable);
    for (const Node& w : n.array("weak_yarns")) d.weak_yarns.push_back(parseWeakYarn(w, d));
    d.seed = seed;
    try {
        validate(d);  // what the fields above cannot check alone: rupture > yield, one density, ...
    } catch (const InvalidInput& e) {
        throw InvalidInput(e.field().empty() ? n.path() : n.path() + "." + e.field(), e.problem());
    }
    if (const auto list = n.field("attachments")) {
        const std::size_t vertices = static_cast<std::size_t>(d.resolution[0]) * static_cast<std::size_t>(d.resolution[1]);
        for (const SheetHold& h : parseSheetAttachments(*list, true, d.resolution[0], d.resolution[1], vertices, "cloth", bodies)) {
            if (h.body) {
                SheetGlue g;
                g.vertex = h.vertex;
                g.body = *h.body;
                g.local = h.local;
                c.glue.push_back(g);
            } else {
                SheetAttachment pin;
                pin.vertex = static_cast<int>(h.vertex);
                pin.world = h.world;
                d.attachments.push_back(pin);
            }
        }
    }
    parseFilter(n, c);
    return c;
}

// =============================================================================================
// Papers
// =============================================================================================

/// A vertex of a sheet: an index, or [i, k] on the rectangle's grid (sheetVertex).
std::uint32_t paperVertex(const Node& n, const PaperDesc& d, std::size_t vertices) {
    return sheetVertex(n, d.vertices.empty(), d.resolution[0], d.resolution[1], vertices, "sheet");
}

/// A paper sheet (SCENE_FORMAT.md, "papers"); `seed` unless it gives "seed".
Paper parsePaper(const Node& n, std::uint64_t seed, const NameMap& bodies) {
    refuseOldSheetWords(n, /*paper=*/true);
    n.checkNoUnknownFields({"name", "center", "corner", "size", "resolution", "orientation", "vertices", "triangles", "areal_density",
                            "stiffness", "bending", "damping", "solver", "tolerance", "jacobi_iterations", "integrator", "phi", "psi",
                            "hinge_threshold", "breakable", "tearable", "rupture_stretch", "tension", "thickness", "friction",
                            "seed", "attachments", "collision_group", "collision_mask"});
    Paper p;
    PaperDesc& d = p.desc;
    d.name = requiredName(n);
    const bool mesh = n.has("vertices") || n.has("triangles");
    if (mesh) {
        for (const char* rect : {"center", "corner", "size", "resolution", "orientation"})
            if (const auto f = n.field(rect)) f->fail("belongs to a rectangle: this sheet gives vertices and triangles");
        for (const Node& v : n.required("vertices").asArray()) d.vertices.push_back(v.asVec3(Range::bullet()));
        for (const Node& t : n.required("triangles").asArray()) {
            const std::vector<Node> ijk = t.asArray();
            if (ijk.size() != 3) t.fail("expected [i, j, k] (3 vertex indices), got " + describe(t.value()));
            const auto count = static_cast<long long>(d.vertices.size());
            std::array<std::uint32_t, 3> tri{};
            for (int c = 0; c < 3; ++c) tri[c] = static_cast<std::uint32_t>(ijk[c].asInteger(0, std::max(0LL, count - 1)));
            d.triangles.push_back(tri);
        }
    } else {
        if (const auto size = n.field("size")) {
            const std::vector<double> v = size->asNumbers(2, Range::leftOpen(0.0, 2.0 * kMaxPosition));
            d.size[0] = v[0];
            d.size[1] = v[1];
        }
        if (const auto res = n.field("resolution")) {
            const std::vector<Node> v = res->asArray();
            if (v.size() != 2) res->fail("expected [nx, nz] (2 integers), got " + describe(res->value()));
            d.resolution[0] = static_cast<int>(v[0].asInteger(2, 1024));
            d.resolution[1] = static_cast<int>(v[1].asInteger(2, 1024));
        }
        if (const auto q = n.field("orientation")) d.orientation = q->asQuaternion();
        parsePlacement(n, d.center, d.corner, std::hypot(d.size[0], d.size[1]));
    }
    d.areal_density = n.number("areal_density", d.areal_density, Range::closed(1e-9, 1e6));
    d.stiffness = n.number("stiffness", d.stiffness, Range::positive());
    d.bending = n.number("bending", d.bending, Range::closed(0.0, 1.0));
    d.damping = n.number("damping", d.damping, Range::closed(0.0, 1.0));
    if (const auto solver = n.field("solver")) {
        const std::string v = solver->asString();
        if (v == "conjugate_gradient") d.solver = PaperSolver::ConjugateGradient;
        else if (v == "multigrid") d.solver = PaperSolver::Multigrid;
        else if (v == "paper") d.solver = PaperSolver::Paper;
        else solver->fail("must be \"conjugate_gradient\", \"multigrid\" or \"paper\" (got " + jsonQuoted(v) + ")");
    }
    d.tolerance = n.number("tolerance", d.tolerance, Range::closed(1e-12, 1e-1));
    d.jacobi_iterations = static_cast<int>(n.integer("jacobi_iterations", d.jacobi_iterations, 1, 256));
    if (const auto integ = n.field("integrator")) {
        const std::string v = integ->asString();
        if (v == "implicit") d.integrator = PaperIntegrator::Implicit;
        else if (v == "explicit") d.integrator = PaperIntegrator::Explicit;
        else integ->fail("must be \"implicit\" or \"explicit\" (got " + jsonQuoted(v) + ")");
    }
    d.phi = n.number("phi", d.phi, Range::leftOpen(0.0, 1000.0));
    d.psi = n.number("psi", d.psi, Range::closed(0.0, 4.0));
    d.hinge_threshold = n.number("hinge_threshold", d.hinge_threshold, Range{0.0, 1.0, false, true});
    d.breakable = n.boolean("breakable", d.breakable);
    d.tearable = n.boolean("tearable", d.tearable);
    d.rupture_stretch = n.number("rupture_stretch", d.rupture_stretch, Range::leftOpen(0.0, 100.0));
    if (const auto t = n.field("tension")) {
        const std::string v = t->asString();
        if (v == "stretch") d.tension = PaperTension::Stretch;
        else if (v == "momentum") d.tension = PaperTension::Momentum;
        else t->fail("must be \"stretch\" or \"momentum\" (got " + jsonQuoted(v) + ")");
    }
    d.thickness = n.number("thickness", d.thickness, Range::leftOpen(0.0, 1.0));
    d.friction = n.number("friction", d.friction, Range::closed(0.0, 100.0));
    d.seed = static_cast<std::uint64_t>(n.integer("seed", static_cast<long long>(seed), 0, LLONG_MAX));
    try {
        validate(d);  // the mesh, ranges the fields above cannot check alone
    } catch (const InvalidInput& e) {
        throw InvalidInput(e.field().empty() ? n.path() : n.path() + "." + e.field(), e.problem());
    }
    const std::size_t vertices = d.vertices.empty() ? static_cast<std::size_t>(d.resolution[0]) * d.resolution[1] : d.vertices.size();
    if (const auto list = n.field("attachments")) {
        for (const SheetHold& h : parseSheetAttachments(*list, d.vertices.empty(), d.resolution[0], d.resolution[1], vertices, "sheet", bodies)) {
            if (h.body) {
                SheetGlue g;
                g.vertex = h.vertex;
                g.body = *h.body;
                g.local = h.local;
                p.glue.push_back(g);
            } else {
                SheetAttachment pin;
                pin.vertex = static_cast<int>(h.vertex);
                pin.world = h.world;
                d.attachments.push_back(pin);
            }
        }
    }
    parseFilter(n, p);
    return p;
}

// =============================================================================================
// Drivers
// =============================================================================================

/// A driver type: its name in the file and the fields it allows.
struct DriverKind {
    const char* name;
    Driver::Type type;
    std::vector<const char*> fields;

    bool allows(const char* field) const {
        return std::any_of(fields.begin(), fields.end(), [&](const char* f) { return std::strcmp(f, field) == 0; });
    }
};

const std::vector<DriverKind>& driverKinds() {
    static const std::vector<DriverKind> kinds = {
        {"force", Driver::Type::Force, {"type", "target", "particle", "vertex", "value", "from", "until"}},
        {"ramp", Driver::Type::Ramp, {"type", "target", "particle", "vertex", "value", "rate", "from", "until"}},
        {"twist", Driver::Type::Twist, {"type", "target", "end", "rate", "from", "until"}},
        {"move", Driver::Type::Move, {"type", "target", "particle", "vertex", "velocity", "from", "until"}},
        {"release", Driver::Type::Release, {"type", "target", "particle", "vertex", "at"}},
        {"wind", Driver::Type::Wind, {"type", "value", "gust", "from", "until"}},
        {"spawn", Driver::Type::Spawn, {"type", "body", "at"}},
        {"velocity", Driver::Type::Velocity, {"type", "body", "value", "from", "until"}},
        {"shoot", Driver::Type::Shoot, {"type", "ray", "impulse", "times", "every", "from", "until"}},
    };
    return kinds;
}

/// A driver; `strings` are the scene's strings (targets), `body_names` all bodies so far
/// (a spawned body's name must be new; it is added).
Driver parseDriver(const Node& n, const std::vector<String>& strings, const std::vector<Cloth>& cloths,
                   const std::vector<Paper>& papers, NameMap& body_names) {
    n.expectObject();
    const Node type = n.required("type");
    const std::string type_name = type.asString();
    const auto& kinds = driverKinds();
    const auto kind = std::find_if(kinds.begin(), kinds.end(), [&](const DriverKind& k) { return type_name == k.name; });
    if (kind == kinds.end()) {
        std::vector<const char*> names;
        for (const DriverKind& k : kinds) names.push_back(k.name);
        type.fail("unknown driver type " + jsonQuoted(type_name) + " (allowed: " + joinNames(names) + ")");
    }
    n.checkNoUnknownFields(kind->fields);

    Driver d;
    d.type = kind->type;
    long long particles = 0;
    const Paper* paper = nullptr;
    if (kind->allows("target")) {
        const Node target = n.required("target");
        d.target = target.asString();
        const auto s = std::find_if(strings.begin(), strings.end(), [&](const String& x) { return x.desc.name == d.target; });
        const auto c = std::find_if(cloths.begin(), cloths.end(), [&](const Cloth& x) { return x.desc.name == d.target; });
        const auto p = std::find_if(papers.begin(), papers.end(), [&](const Paper& x) { return x.desc.name == d.target; });
        const bool on_vertex = d.type != Driver::Type::Twist;             // cloth vertices: force, ramp, move, release
        const bool on_paper = d.type == Driver::Type::Force || d.type == Driver::Type::Move;  // paper vertices
        if (s != strings.end()) {
            particles = static_cast<long long>(s->desc.points.size());
            if (const auto v = n.field("vertex")) v->fail("only for a cloth or paper target (a string's is particle)");
        } else if (c != cloths.end() && on_vertex) {
            d.cloth = true;
            if (const auto particle = n.field("particle")) particle->fail("a cloth's vertex is given as vertex: [i, j]");
            const Node vertex = n.required("vertex");
            const auto [i, j] = clothVertex(vertex, c->desc);
            d.particle = j * c->desc.resolution[0] + i;
        } else if (p != papers.end() && on_paper) {
            paper = &*p;
        } else {
            std::vector<std::string> names;
            for (const String& x : strings) names.push_back(x.desc.name);
            if (on_vertex)
                for (const Cloth& x : cloths) names.push_back(x.desc.name);
            if (on_paper)
                for (const Paper& x : papers) names.push_back(x.desc.name);
            const std::string what = !on_vertex ? "string" : on_paper ? "string, cloth or paper" : "string or cloth";
            const std::string plural = !on_vertex ? "strings" : on_paper ? "strings, cloths and papers" : "strings and cloths";
            target.fail("no " + what + " named " + jsonQuoted(d.target) + knownNames(names, plural));
        }
    }
    if (paper) {
        if (const auto particle = n.field("particle")) particle->fail("a paper's vertex is given as \"vertex\"");
        const PaperDesc& pd = paper->desc;
        const std::size_t vertices = pd.vertices.empty() ? static_cast<std::size_t>(pd.resolution[0]) * pd.resolution[1] : pd.vertices.size();
        d.paper_vertex = static_cast<int>(paperVertex(n.required("vertex"), pd, vertices));
    }
    if (kind->allows("particle") && !d.cloth && !paper) {
        const auto p = n.field("particle");
        d.particle = p ? particleIndex(*p, particles) : static_cast<int>(particles - 1);
    }

    switch (d.type) {
        case Driver::Type::Force: d.value = n.required("value").asVec3AtMost(kMaxForce, "N"); break;
        case Driver::Type::Ramp: {
            const Node value = n.required("value");
            d.value = value.asVec3();
            if (!(d.value.norm() > 1e-12)) value.fail("must be a non-zero direction");
            d.value.normalize();
            d.rate = n.required("rate").asNumber(Range::leftOpen(0.0, kMaxRampRate));
            break;
        }
        case Driver::Type::Twist: {
            if (const auto end = n.field("end")) {
                const long long e = end->asInteger();
                if (e != 0 && e != -1) end->fail("must be 0 (the first end) or -1 (the last end) (got " + std::to_string(e) + ")");
                d.end = static_cast<int>(e);
            }
            d.rate = n.required("rate").asNumber(Range::closed(-kMaxTwistRate, kMaxTwistRate));
            break;
        }
        case Driver::Type::Move: d.velocity = n.required("velocity").asVec3AtMost(kMaxSpeed, "m/s"); break;
        case Driver::Type::Release: break;
        case Driver::Type::Wind:
            d.value = n.required("value").asVec3AtMost(kMaxSpeed, "m/s");
            d.gust = n.number("gust", d.gust, Range::closed(0.0, 10.0));
            break;
        case Driver::Type::Velocity: {
            const Node body = n.required("body");
            d.body_name = body.asString();
            if (body_names.count(d.body_name) == 0)
                body.fail("no body named " + jsonQuoted(d.body_name) + knownNames(namesOf(body_names), "bodies"));
            d.value = n.required("value").asVec3AtMost(kMaxSpeed, "m/s");
            break;
        }
        case Driver::Type::Spawn: {
            const Node body = n.required("body");
            d.body = parseBody(body);
            claimName(body_names, d.body->name, body.path(), "body");
            break;
        }
        case Driver::Type::Shoot: {
            const Node ray = n.required("ray");
            ray.checkNoUnknownFields({"from", "to"});
            d.ray_from = ray.required("from").asVec3(Range::bullet());
            const Node to = ray.required("to");
            d.ray_to = to.asVec3(Range::bullet());
            if (!((d.ray_to - d.ray_from).norm() >= 1e-3))
                to.fail("must be at least 1 mm from ray.from (the ray needs a direction)");
            d.impulse = n.required("impulse").asPositiveAtMost(1e6);
            break;
        }
    }

    if (kind->allows("from")) d.from = n.number("from", d.from, Range::atLeast(0.0));
    if (kind->allows("until")) {
        if (const auto until = n.field("until")) {
            d.until = until->asNumber();
            if (!(d.until > d.from))
                until->fail("must be greater than from (got " + formatNumber(d.until) + " <= " + formatNumber(d.from) + ")");
        }
    }
    if (kind->allows("at")) d.at = n.number("at", d.at, Range::atLeast(0.0));
    if (d.type == Driver::Type::Shoot) {
        // The shots: listed ("times"), or one every so many seconds between from and until.
        const auto times = n.field("times");
        const auto every = n.field("every");
        if (times && every) every->fail("give either times or every, not both");
        if (times) {
            for (const char* key : {"from", "until"})
                if (const auto f = n.field(key)) f->fail("only with every (times lists the shots)");
            const std::vector<Node> list = times->asArray();
            if (list.empty()) times->fail("must list at least one time");
            if (list.size() > 100000) times->fail("at most 100000 shots");
            for (const Node& t : list) {
                const double v = t.asNumber(Range::closed(0.0, 1e9));
                if (!d.times.empty() && !(v > d.times.back()))
                    t.fail("must be after the time before it (got " + formatNumber(v) + " <= " + formatNumber(d.times.back()) + ")");
                d.times.push_back(v);
            }
        } else if (every) {
            const double period = every->asNumber(Range::leftOpen(0.0, 1e9));
            if (!n.has("until")) throw InvalidInput(memberPath(n.path(), "until"), "missing required field (with every, the shots end at until)");
            const double count = std::floor((d.until - d.from) / period);
            if (!(count < 100000)) every->fail("makes more than 100000 shots between from and until");
            for (double k = 0; k <= count; ++k)
                if (d.from + k * period < d.until) d.times.push_back(d.from + k * period);
        } else {
            throw InvalidInput(memberPath(n.path(), "times"), "missing required field (or every, with from and until)");
        }
    }
    return d;
}

// =============================================================================================
// The scene
// =============================================================================================

/// The optional picture camera: {"eye": [..], "target": [..], "fov": degrees}.
Camera parseCamera(const Node& n) {
    n.checkNoUnknownFields({"eye", "target", "fov"});
    Camera c;
    if (const auto eye = n.field("eye")) c.eye = eye->asVec3();
    if (const auto target = n.field("target")) c.target = target->asVec3();
    c.fov = n.number("fov", c.fov, Range{1.0, 170.0, true, true});
    if (c.eye && c.target && (*c.eye - *c.target).norm() < 1e-9)
        n.required("target").fail("must differ from eye (the camera needs a direction to look in)");
    return c;
}

}  // namespace

Scene parseScene(const std::string& json_text) {
    const json root = parseJson(json_text);
    if (!root.is_object()) throw InvalidInput("", "a scene must be a JSON object, got " + describe(root));
    const Node top(root, "");

    // The format first: a newer one may have fields this build does not know.
    if (const auto format = top.field("format")) {
        const std::string f = format->asString();
        if (f != kFormat)
            format->fail("unsupported format " + jsonQuoted(f) + " (this build reads " + jsonQuoted(kFormat) + ")");
    }
    top.checkNoUnknownFields({"format", "description", "camera", "dt", "steps", "gravity", "seed", "bodies",
                              "joints", "strings", "papers", "cloths", "drivers", "output"});
    if (const auto description = top.field("description")) description->asString();
    Scene scene;
    if (const auto camera = top.field("camera")) scene.camera = parseCamera(*camera);
    scene.dt = top.number("dt", scene.dt, Range::leftOpen(0.0, 0.1));
    scene.steps = top.integer("steps", scene.steps, 0, 1'000'000'000);
    scene.gravity = top.vec3("gravity", scene.gravity, Range::bullet());
    scene.seed = static_cast<std::uint64_t>(top.integer("seed", static_cast<long long>(scene.seed), 0, LLONG_MAX));

    NameMap body_names;
    for (const Node& n : top.array("bodies")) {
        scene.bodies.push_back(parseBody(n));
        claimName(body_names, scene.bodies.back().name, n.path(), "body");
    }
    for (const Node& n : top.array("joints")) scene.joints.push_back(parseJoint(n, body_names, scene.bodies));

    NameMap string_names;
    const std::vector<Node> strings = top.array("strings");
    for (std::size_t i = 0; i < strings.size(); ++i) {
        scene.strings.push_back(parseString(strings[i], scene.seed + i, body_names));
        claimName(string_names, scene.strings.back().desc.name, strings[i].path(), "string");
    }

    const std::vector<Node> cloths = top.array("cloths");
    for (std::size_t i = 0; i < cloths.size(); ++i) {
        scene.cloths.push_back(parseCloth(cloths[i], scene.seed + strings.size() + i, body_names));
        claimName(string_names, scene.cloths.back().desc.name, cloths[i].path(), "string or cloth");
    }
    // Strings, cloths and papers share one namespace: a driver's target names one of them.
    const std::vector<Node> papers = top.array("papers");
    for (std::size_t i = 0; i < papers.size(); ++i) {
        scene.papers.push_back(parsePaper(papers[i], scene.seed + 1000 + i, body_names));
        claimName(string_names, scene.papers.back().desc.name, papers[i].path(), "paper");
    }

    for (const Node& n : top.array("drivers"))
        scene.drivers.push_back(parseDriver(n, scene.strings, scene.cloths, scene.papers, body_names));

    if (const auto output = top.field("output")) {
        output->checkNoUnknownFields({"every"});
        scene.output_every = static_cast<int>(output->integer("every", scene.output_every, 1, 1'000'000'000));
    }
    return scene;
}

Scene loadSceneFile(const std::string& path) {
    const std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
    if (!file) throw std::runtime_error("cannot read " + path + ": " + std::strerror(errno));
    std::string text;
    char buffer[1 << 16];
    std::size_t n = 0;
    while ((n = std::fread(buffer, 1, sizeof buffer, file.get())) > 0) text.append(buffer, n);
    if (std::ferror(file.get())) throw std::runtime_error("cannot read " + path + ": " + std::strerror(errno));
    Scene scene = parseScene(text);
    scene.source = path;
    return scene;
}

}  // namespace tearables::scene
