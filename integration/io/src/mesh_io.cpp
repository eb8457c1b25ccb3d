// mesh_io.cpp: assimp import (triangles, welding, named groups) and export (order-preserving).
#include "drape/io/mesh_io.hpp"

#include <drape/error.hpp>
#include <drape/topology.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#if DRAPE_IO_HAVE_ASSIMP
#include "assimp_io.hpp"

#include <assimp/Exporter.hpp>
#include <nlohmann/json.hpp>
#include <pthread.h>

#include <assimp/Importer.hpp>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <exception>
#endif

namespace drape::io {

namespace {

[[noreturn]] void meshFail(const std::filesystem::path& file, const std::string& what) {
    throw Error(ErrorCode::FileError, file.string() + ": " + what);
}

} // namespace

void transformMesh(TriangleMesh& mesh, const Vec3& scale, const Vec3& rotationDeg,
                   const Vec3& translation) {
    const double d2r = 3.14159265358979323846 / 180.0;
    const Eigen::Matrix3d r = (Eigen::AngleAxisd(rotationDeg.z() * d2r, Vec3::UnitZ()) *
                               Eigen::AngleAxisd(rotationDeg.y() * d2r, Vec3::UnitY()) *
                               Eigen::AngleAxisd(rotationDeg.x() * d2r, Vec3::UnitX()))
                                  .toRotationMatrix();
    for (Vec3& v : mesh.vertices)
        v = r * v.cwiseProduct(scale) + translation;
    // A mirroring scale flips every triangle; restore counter-clockwise order.
    if (scale.x() * scale.y() * scale.z() < 0.0)
        for (Triangle& t : mesh.triangles)
            std::swap(t[1], t[2]);
}

ImportedMesh importMesh(const std::filesystem::path& file, std::optional<double> weldTolerance) {
    MeshImportOptions o;
    o.weldTolerance = weldTolerance;
    return importMesh(file, o);
}

#if DRAPE_IO_HAVE_ASSIMP

bool available() {
    return true;
}

namespace {

std::string lowerExtension(const std::filesystem::path& file) {
    std::string ext = file.extension().string();
    for (char& ch : ext)
        ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return ext;
}

/// True for a PLY file (it starts with "ply", as assimp's PLY reader demands; whatever follows,
/// a NUL byte included) whose header never ends: assimp 5.2's PLY reader then waits forever
/// at the end of the file for a line that starts with the token "end_header" (leading
/// blanks allowed).
bool isPlyWithoutEndHeader(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    std::string line;
    if (!std::getline(in, line) || line.compare(0, 3, "ply") != 0) return false;
    const std::string token = "end_header";
    while (std::getline(in, line)) {
        const std::size_t start = line.find_first_not_of(" \t");
        if (start == std::string::npos || line.compare(start, token.size(), token) != 0) continue;
        const std::size_t after = start + token.size();
        if (after == line.size() || std::isspace(static_cast<unsigned char>(line[after])))
            return false;
    }
    return true;
}

/// True for a PLY file whose header declares triangle strips (`element tristrips`): assimp
/// 5.2's PLY reader keeps one triangle of them (a review's 268k-triangle head came in as one
/// triangle and three particles, with no error).
bool isPlyWithTriangleStrips(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    std::string line;
    if (!std::getline(in, line) || line.compare(0, 3, "ply") != 0) return false;
    while (std::getline(in, line)) {
        std::istringstream words(line);
        std::string first, second;
        words >> first >> second;
        if (first == "end_header") return false;
        if (first == "element" && second == "tristrips") return true;
    }
    return false;
}

/// A count from a file header, as written (digits only), and its value (saturated).
struct Count {
    std::string text;
    std::uint64_t value = 0;
};

/// The count assimp reads from `token`: its leading decimal digits, as assimp's strtoul10
/// does ("12abc" is 12; assimp wraps long numbers to 32 bits, here they saturate, which only
/// makes the check stricter). False if the token starts with no digit (assimp reads 0).
bool parseCount(const std::string& token, Count& out) {
    std::size_t n = 0;
    while (n < token.size() && token[n] >= '0' && token[n] <= '9')
        ++n;
    if (n == 0) return false;
    out.text = token.substr(0, n);
    out.value = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const auto d = static_cast<std::uint64_t>(token[i] - '0');
        out.value = out.value > (UINT64_MAX - d) / 10 ? UINT64_MAX : out.value * 10 + d;
    }
    return true;
}

std::string bytesText(std::uint64_t n) {
    return std::to_string(n) + (n == 1 ? " byte" : " bytes");
}

/// Collada arrays (<float_array count="N">v1 v2 ...</float_array>, and the int, bool, Name
/// and IDREF arrays) must hold exactly the count they declare: assimp sizes the array from
/// the count and reads the values into it, so fewer declared than written writes past it.
void checkColladaArrays(const std::filesystem::path& file, const std::string& text) {
    static const char* kinds[] = {"float_array", "int_array", "bool_array", "Name_array",
                                  "IDREF_array"};
    for (const char* kind : kinds) {
        const std::string open = std::string("<") + kind;
        for (std::size_t at = text.find(open); at != std::string::npos;
             at = text.find(open, at + 1)) {
            const std::size_t after = at + open.size();
            if (after >= text.size() || !(std::isspace(static_cast<unsigned char>(text[after])) ||
                                          text[after] == '>' || text[after] == '/'))
                continue;
            const std::size_t tagEnd = text.find('>', after);
            if (tagEnd == std::string::npos) return; // assimp refuses the broken XML
            const std::string tag = text.substr(at, tagEnd - at);
            const std::size_t key = tag.find("count=\"");
            std::string where = "<" + std::string(kind) + ">";
            if (const std::size_t id = tag.find("id=\""); id != std::string::npos) {
                const std::size_t idEnd = tag.find('"', id + 4);
                if (idEnd != std::string::npos)
                    where += " \"" + tag.substr(id + 4, std::min<std::size_t>(idEnd - id - 4, 64)) +
                             "\"";
            }
            if (key == std::string::npos)
                meshFail(file, "Collada " + where + " has no count attribute");
            const std::size_t valueStart = key + 7;
            const std::size_t valueEnd = tag.find('"', valueStart);
            const std::string value =
                valueEnd == std::string::npos ? "" : tag.substr(valueStart, valueEnd - valueStart);
            Count c;
            if (!parseCount(value, c) || c.text.size() != value.size())
                meshFail(file, "Collada " + where + " count=\"" + value.substr(0, 32) +
                                   "\" is not a non-negative whole number");
            std::uint64_t values = 0;
            if (text[tagEnd - 1] != '/') { // not <x/>: count the values up to the closing tag
                const std::size_t close = text.find("</", tagEnd);
                const std::size_t end = close == std::string::npos ? text.size() : close;
                bool inToken = false;
                for (std::size_t i = tagEnd + 1; i < end; ++i) {
                    const bool space = std::isspace(static_cast<unsigned char>(text[i])) != 0;
                    values += !space && !inToken;
                    inToken = !space;
                }
            }
            if (values != c.value)
                meshFail(file, "Collada " + where + " declares count=\"" + c.text +
                                   "\" but holds " + std::to_string(values) + " values");
        }
    }
}

/// Collada <node> elements nested deeper than kMaxNodeDepth.
void checkColladaDepth(const std::filesystem::path& file, const std::string& text) {
    std::size_t depth = 0;
    for (std::size_t at = text.find('<'); at != std::string::npos; at = text.find('<', at + 1)) {
        const bool closing = text.compare(at, 6, "</node") == 0;
        if (!closing && text.compare(at, 5, "<node") != 0) continue;
        const std::size_t after = at + (closing ? 6 : 5);
        if (after < text.size() && !(std::isspace(static_cast<unsigned char>(text[after])) ||
                                     text[after] == '>' || text[after] == '/'))
            continue; // <nodes>, <node_x>
        if (closing) {
            depth -= depth > 0;
            continue;
        }
        const std::size_t tagEnd = text.find('>', after);
        if (tagEnd != std::string::npos && text[tagEnd - 1] == '/') continue; // <node/>
        if (++depth > kMaxNodeDepth)
            meshFail(file, "Collada nodes nested deeper than " + std::to_string(kMaxNodeDepth) +
                               " levels");
    }
}

/// glTF node trees deeper than kMaxNodeDepth, or whose children form a cycle: read from the
/// JSON (a .gltf file, or a .glb's first chunk) before assimp walks them recursively.
void checkGltfDepth(const std::filesystem::path& file, std::ifstream& in, bool binary) {
    in.clear();
    in.seekg(0);
    std::string json;
    if (binary) {
        unsigned char head[20];
        if (!in.read(reinterpret_cast<char*>(head), sizeof head)) return; // assimp refuses it
        auto u32 = [&head](int at) {
            return std::uint32_t(head[at]) | std::uint32_t(head[at + 1]) << 8 |
                   std::uint32_t(head[at + 2]) << 16 | std::uint32_t(head[at + 3]) << 24;
        };
        if (u32(0) != 0x46546C67u || u32(16) != 0x4E4F534Au) return; // "glTF", "JSON"
        json.resize(u32(12));
        if (!in.read(json.data(), static_cast<std::streamsize>(json.size()))) return;
    } else {
        json.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    const nlohmann::json doc = nlohmann::json::parse(json, nullptr, false);
    if (!doc.is_object() || !doc.contains("nodes") || !doc["nodes"].is_array()) return;
    const auto& nodes = doc["nodes"];
    const std::size_t n = nodes.size();
    std::vector<std::vector<std::size_t>> children(n);
    std::vector<unsigned char> isChild(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
        if (!nodes[i].is_object() || !nodes[i].contains("children")) continue;
        for (const auto& c : nodes[i]["children"]) {
            if (!c.is_number_unsigned() || c.get<std::uint64_t>() >= n) continue;
            children[i].push_back(std::size_t(c.get<std::uint64_t>()));
            isChild[children[i].back()] = 1;
        }
    }
    // Depth-first from every root, with an explicit stack (no recursion here either).
    std::vector<unsigned char> state(n, 0);                // 0 unseen, 1 on the path, 2 done
    std::vector<std::pair<std::size_t, std::size_t>> path; // (node, next child)
    for (std::size_t root = 0; root < n; ++root) {
        if (isChild[root] || state[root]) continue;
        path.assign(1, {root, 0});
        state[root] = 1;
        while (!path.empty()) {
            auto& [node, next] = path.back();
            if (next == children[node].size()) {
                state[node] = 2;
                path.pop_back();
                continue;
            }
            const std::size_t child = children[node][next++];
            if (state[child] == 1)
                meshFail(file, "glTF node " + std::to_string(child) + " is its own ancestor");
            if (state[child] == 2) continue;
            state[child] = 1;
            path.emplace_back(child, 0);
            if (path.size() > kMaxNodeDepth)
                meshFail(file, "glTF nodes nested deeper than " + std::to_string(kMaxNodeDepth) +
                                   " levels");
        }
    }
    for (std::size_t i = 0; i < n; ++i)
        if (state[i] == 0)
            meshFail(file, "glTF node " + std::to_string(i) + " lies on a cycle of children");
}

/// Vertex positions ("v" lines) of an OBJ file that no face, line or point uses: assimp's
/// reader leaves them out of its meshes, so drape's own count of unused vertices cannot see
/// them. Indices as OBJ has them: 1-based, or negative counting back from the last "v".
std::size_t unusedObjVertices(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    std::vector<unsigned char> used;
    std::string line;
    while (std::getline(in, line)) {
        std::size_t at = line.find_first_not_of(" \t");
        if (at == std::string::npos || at + 1 >= line.size()) continue;
        const char kind = line[at];
        const char next = line[at + 1];
        if (kind == 'v' && (next == ' ' || next == '\t')) {
            used.push_back(0);
            continue;
        }
        if (!((kind == 'f' || kind == 'l' || kind == 'p') && (next == ' ' || next == '\t')))
            continue;
        std::istringstream ss(line.substr(at + 2));
        std::string token;
        while (ss >> token) {
            const std::size_t slash = token.find('/');
            const std::string first = token.substr(0, slash);
            char* end = nullptr;
            const long long k = std::strtoll(first.c_str(), &end, 10);
            if (end == first.c_str()) continue;
            const long long n = static_cast<long long>(used.size());
            const long long i = k > 0 ? k - 1 : n + k;
            if (i >= 0 && i < n) used[std::size_t(i)] = 1;
        }
    }
    return static_cast<std::size_t>(std::count(used.begin(), used.end(), 0));
}

/// Header counts larger than the file can hold: assimp allocates what a header claims before
/// it reads the data (a binary STL's triangle count, a PLY element count, an OFF vertex
/// count), so a 200-byte file claiming billions of vertices ends in std::bad_alloc or in
/// gigabytes of memory. Each count is checked against the least the file needs to hold it.
void checkHeaderCounts(const std::filesystem::path& file, const std::string& ext,
                       std::uint64_t size) {
    std::ifstream in(file, std::ios::binary);
    if (ext == ".stl") {
        char head[84];
        if (!in.read(head, sizeof head)) return; // assimp refuses files this short
        std::size_t i = 0;
        while (i < 80 && std::isspace(static_cast<unsigned char>(head[i])))
            ++i;
        if (std::string(head + i, std::min<std::size_t>(5, 80 - i)) == "solid") return; // ASCII
        const std::uint64_t count =
            static_cast<std::uint64_t>(static_cast<unsigned char>(head[80])) |
            static_cast<std::uint64_t>(static_cast<unsigned char>(head[81])) << 8 |
            static_cast<std::uint64_t>(static_cast<unsigned char>(head[82])) << 16 |
            static_cast<std::uint64_t>(static_cast<unsigned char>(head[83])) << 24;
        const std::uint64_t need = 84 + 50 * count;
        if (need > size)
            meshFail(file, "binary STL header claims " + std::to_string(count) +
                               " triangles, which need " + bytesText(need) +
                               " (84 + 50 per triangle), but the file has only " + bytesText(size));
        return;
    }
    if (ext == ".ply") {
        std::string line;
        if (!std::getline(in, line) || line.compare(0, 3, "ply") != 0) return;
        bool binary = false;
        struct Element {
            std::string name;
            Count count;
            std::uint64_t minBytes = 0; // per element
            bool known = true;          // no property assimp cannot parse yet
        };
        std::vector<Element> elements;
        auto typeSize = [](const std::string& t) -> std::uint64_t {
            if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
            if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
            if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" ||
                t == "float32")
                return 4;
            if (t == "double" || t == "float64") return 8;
            return 0;
        };
        bool ended = false;
        while (std::getline(in, line)) {
            std::istringstream ss(line);
            std::string word;
            ss >> word;
            if (word == "end_header") {
                ended = true;
                break;
            }
            if (word == "format") {
                std::string f;
                ss >> f;
                binary = f.rfind("binary", 0) == 0;
            } else if (word == "element") {
                Element e;
                std::string n;
                ss >> e.name >> n;
                // assimp 5.2 reads the count from the token after the name, except for names
                // it does not know, where it reads it from the name itself ("element 9999
                // vertex"): take the larger of the two.
                Count fromName;
                if (!parseCount(n, e.count)) e.count = Count{"0", 0};
                if (parseCount(e.name, fromName) && fromName.value > e.count.value)
                    e.count = fromName;
                elements.push_back(e);
            } else if (word == "property" && !elements.empty() && elements.back().known) {
                // assimp ends an element's property list at the first property it cannot
                // parse; the element keeps those before it.
                Element& e = elements.back();
                std::string type;
                ss >> type;
                std::uint64_t bytes = 0;
                if (type == "list") {
                    std::string countType;
                    ss >> countType;
                    bytes = typeSize(countType); // an empty list: just its count
                } else {
                    bytes = typeSize(type);
                }
                if (bytes == 0)
                    e.known = false;
                else
                    e.minBytes += binary ? bytes : 2; // ASCII: a digit and a separator
            }
        }
        if (!ended) return;
        const auto header = static_cast<std::uint64_t>(in.tellg());
        const std::uint64_t body = size > header ? size - header : 0;
        // ASCII: the last value needs no separator after it.
        std::uint64_t left = binary ? body : body + 1;
        for (const Element& e : elements) {
            const std::uint64_t per = std::max<std::uint64_t>(1, e.minBytes);
            if (e.count.value > left / per)
                meshFail(file, "PLY header claims " + e.count.text + " \"" + e.name +
                                   "\" elements, at least " + bytesText(per) +
                                   " each, but the file has only " + bytesText(body) +
                                   " after its header");
            left -= e.count.value * per;
        }
        return;
    }
    if (ext == ".dae") {
        // Collada: count="N" of arrays, accessors and primitives counts items written in the
        // file itself, at least a byte each.
        const std::string text{std::istreambuf_iterator<char>(in),
                               std::istreambuf_iterator<char>()};
        const std::string key = "count=\"";
        for (std::size_t at = text.find(key); at != std::string::npos;
             at = text.find(key, at + 1)) {
            if (at == 0 || !std::isspace(static_cast<unsigned char>(text[at - 1]))) continue;
            const std::size_t start = at + key.size();
            const std::size_t end = text.find('"', start);
            Count c;
            if (end == std::string::npos || !parseCount(text.substr(start, end - start), c) ||
                c.value <= size)
                continue;
            const std::size_t open = text.rfind('<', at);
            std::size_t nameEnd = open == std::string::npos ? open : open + 1;
            while (nameEnd < at && !std::isspace(static_cast<unsigned char>(text[nameEnd])))
                ++nameEnd;
            const std::string element = open == std::string::npos
                                            ? std::string("an element")
                                            : "<" + text.substr(open + 1, nameEnd - open - 1) + ">";
            meshFail(file, "Collada " + element + " claims count=\"" + c.text +
                               "\", more items than the file (" + bytesText(size) + ") can hold");
        }
        checkColladaArrays(file, text);
        checkColladaDepth(file, text);
        return;
    }
    if (ext == ".gltf" || ext == ".glb") {
        checkGltfDepth(file, in, ext == ".glb");
        return;
    }
    if (ext == ".off") {
        // [ST][C][N][4][n]OFF [dim] nv nf ne, '#' comments; assimp reads 32-bit counts.
        std::string token;
        std::vector<std::string> tokens;
        std::string line;
        while (tokens.size() < 5 && std::getline(in, line)) {
            const std::size_t hash = line.find('#');
            std::istringstream ss(line.substr(0, hash));
            while (ss >> token)
                tokens.push_back(token);
        }
        if (tokens.empty()) return;
        std::size_t at = 0;
        std::uint64_t dims = 3;
        const std::string& keyword = tokens[0];
        if (keyword.size() >= 3 && keyword.compare(keyword.size() - 3, 3, "OFF") == 0) {
            ++at;
            if (keyword.find('n') != std::string::npos) {
                Count d;
                if (at >= tokens.size() || !parseCount(tokens[at], d)) return;
                dims = std::max<std::uint64_t>(1, std::min<std::uint64_t>(d.value, 3));
                ++at;
            }
        }
        Count nv, nf;
        if (at + 1 >= tokens.size() || !parseCount(tokens[at], nv) ||
            !parseCount(tokens[at + 1], nf))
            return;
        // A vertex is at least dims numbers of one digit and their separators; a face at
        // least a number and a line break.
        auto times = [](std::uint64_t n, std::uint64_t k) {
            return n > UINT64_MAX / k ? UINT64_MAX : n * k;
        };
        const std::uint64_t vertexBytes = times(nv.value, 2 * dims);
        const std::uint64_t faceBytes = times(nf.value, 2);
        const std::uint64_t need =
            vertexBytes > UINT64_MAX - faceBytes ? UINT64_MAX : vertexBytes + faceBytes;
        if (need > size + 1)
            meshFail(file, "OFF header claims " + nv.text + " vertices and " + nf.text +
                               " faces, which need at least " + bytesText(need - 1) +
                               ", but the file has only " + bytesText(size));
    }
}

struct RawMesh {
    TriangleMesh mesh;
    std::map<std::string, std::vector<Index>> rawGroups; // raw vertex indices
    std::size_t skipped = 0;                             // the file's points and lines
    // Where each triangle comes from: the scene's mesh and its face (after triangulation).
    std::vector<std::pair<unsigned, unsigned>> origin;
    // Triangles FindDegenerates collapsed to lines or points, as (mesh, face).
    std::vector<std::pair<unsigned, unsigned>> collapsed;
};

/// Faces of each mesh that were triangles before FindDegenerates ran, to tell a triangle it
/// collapsed (to a line or a point) from the file's own lines and points.
using TriangleMasks = std::map<const aiMesh*, std::vector<unsigned char>>;

/// The groups the vertices of mesh m under `node` belong to. An OBJ file's groups are its
/// `g` (and `o`) names, which assimp gives as the node's name: "g a b" puts the faces in two
/// groups, a and b. Assimp's OBJ reader names its meshes after their materials (`usemtl`),
/// which are no groups: a material named like a group would add its faces to it. Other formats
/// name meshes and nodes (glTF meshes and nodes, 3DS objects): both count.
std::vector<std::string> groupNames(const aiMesh& m, const aiNode& node,
                                    const std::filesystem::path& file) {
    std::vector<std::string> names;
    const std::string nodeName = node.mName.C_Str();
    if (lowerExtension(file) == ".obj") {
        std::istringstream words(nodeName);
        for (std::string w; words >> w;)
            if (std::find(names.begin(), names.end(), w) == names.end()) names.push_back(w);
        return names;
    }
    for (std::string name : {std::string(m.mName.C_Str()), nodeName})
        if (!name.empty() && std::find(names.begin(), names.end(), name) == names.end())
            names.push_back(std::move(name));
    return names;
}

void gather(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent, RawMesh& out,
            const TriangleMasks& wasTriangle, const std::filesystem::path& file) {
    const aiMatrix4x4 world = parent * node.mTransformation;
    for (unsigned k = 0; k < node.mNumMeshes; ++k) {
        if (node.mMeshes[k] >= scene.mNumMeshes) meshFail(file, "node refers to a missing mesh");
        const unsigned meshIndex = node.mMeshes[k];
        const aiMesh& m = *scene.mMeshes[meshIndex];
        const std::size_t base = out.mesh.vertices.size();
        if (base + m.mNumVertices > kMaxMeshVertices * 8)
            meshFail(file, "too many vertices (limit " + std::to_string(kMaxMeshVertices * 8) +
                               " before welding)");
        for (unsigned i = 0; i < m.mNumVertices; ++i) {
            const aiVector3D p = world * m.mVertices[i];
            const Vec3 v(p.x, p.y, p.z);
            if (!v.allFinite())
                meshFail(file, "vertex " + std::to_string(i) + " of mesh \"" + m.mName.C_Str() +
                                   "\" is not finite");
            out.mesh.vertices.push_back(v);
        }
        const auto mask = wasTriangle.find(&m);
        for (unsigned f = 0; f < m.mNumFaces; ++f) {
            const aiFace& face = m.mFaces[f];
            if (face.mNumIndices != 3) {
                const bool collapsed =
                    mask != wasTriangle.end() && f < mask->second.size() && mask->second[f];
                if (collapsed)
                    out.collapsed.emplace_back(meshIndex, f);
                else
                    ++out.skipped;
                continue;
            }
            Triangle t{};
            for (unsigned c = 0; c < 3; ++c) {
                if (face.mIndices[c] >= m.mNumVertices)
                    meshFail(file, "face " + std::to_string(f) + " of mesh \"" + m.mName.C_Str() +
                                       "\" has an index out of range");
                t[c] = static_cast<Index>(base + face.mIndices[c]);
            }
            out.mesh.triangles.push_back(t);
            out.origin.emplace_back(meshIndex, f);
        }
        std::vector<Index> all(m.mNumVertices);
        for (unsigned i = 0; i < m.mNumVertices; ++i)
            all[i] = static_cast<Index>(base + i);
        for (const std::string& name : groupNames(m, node, file)) {
            auto& g = out.rawGroups[name];
            g.insert(g.end(), all.begin(), all.end());
        }
    }
    for (unsigned c = 0; c < node.mNumChildren; ++c)
        gather(scene, *node.mChildren[c], world, out, wasTriangle, file);
}

/// "mesh \"body\" faces 3, 17, 40 and 5 more; mesh \"hat\" face 2": where the listed
/// (mesh, face) pairs are, the first few of each mesh.
std::string whereText(std::vector<std::pair<unsigned, unsigned>> faces,
                      const std::vector<std::string>& meshNames) {
    std::sort(faces.begin(), faces.end());
    constexpr std::size_t kShown = 8;
    std::string out;
    for (std::size_t i = 0; i < faces.size();) {
        const unsigned mesh = faces[i].first;
        std::size_t j = i;
        while (j < faces.size() && faces[j].first == mesh)
            ++j;
        const std::string& name = mesh < meshNames.size() ? meshNames[mesh] : std::string();
        out += (out.empty() ? "" : "; ") +
               (name.empty() ? "mesh " + std::to_string(mesh) : "mesh \"" + name + "\"") +
               (j - i == 1 ? " face " : " faces ");
        for (std::size_t k = i; k < j && k < i + kShown; ++k)
            out += (k == i ? "" : ", ") + std::to_string(faces[k].second);
        if (j - i > kShown) out += " and " + std::to_string(j - i - kShown) + " more";
        i = j;
    }
    return out;
}

/// Stack of the thread that runs an import [bytes]: assimp's readers, post-processing and
/// scene destructor recurse over node trees (checked to at most kMaxNodeDepth levels for the
/// formats that can nest deeply; this covers the others' recursion too).
constexpr std::size_t kImportStackBytes = std::size_t(256) << 20;

ImportedMesh importOnThisStack(const std::filesystem::path& file, const MeshImportOptions& options);

/// A warning for edges no cloth surface has (empty when there are none): mostly border edges
/// (loose triangles, see kLooseTriangles), edges shared by more
/// than two triangles (a fin or a pinch: the cloth simulates them, one spring per edge, but
/// its two sides, the aerodynamics and the self-collision assume a surface), and edges whose
/// two triangles are wound against each other (the normals flip across them: the lift and the
/// shading follow the winding). Names up to three of each.
/// The fewest triangles for which a mesh of mostly border edges is called loose (a strip of a
/// few triangles has mostly border edges).
constexpr std::size_t kLooseTriangles = 32;

std::string surfaceWarning(const TriangleMesh& mesh) {
    struct Use {
        Index lo, hi;
        bool forward; ///< the triangle runs lo -> hi
        bool operator<(const Use& o) const {
            return lo != o.lo ? lo < o.lo : hi != o.hi ? hi < o.hi : forward < o.forward;
        }
    };
    std::vector<Use> uses;
    uses.reserve(3 * mesh.triangles.size());
    for (const Triangle& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) {
            const Index a = t[k], b = t[(k + 1) % 3];
            uses.push_back({std::min(a, b), std::max(a, b), a < b});
        }
    std::sort(uses.begin(), uses.end());
    std::size_t fins = 0, flips = 0, edges = 0, borders = 0;
    std::string finExamples, flipExamples;
    auto name = [](std::string& list, const Use& u, std::size_t n) {
        char buf[96];
        std::snprintf(buf, sizeof buf, "%svertices %u and %u", list.empty() ? "" : "; ",
                      unsigned(u.lo), unsigned(u.hi));
        if (n <= 3) list += buf;
    };
    for (std::size_t b = 0; b < uses.size();) {
        std::size_t e = b, forward = 0;
        while (e < uses.size() && uses[e].lo == uses[b].lo && uses[e].hi == uses[b].hi)
            forward += uses[e++].forward;
        const std::size_t count = e - b;
        ++edges;
        borders += count == 1;
        if (count > 2) {
            name(finExamples, uses[b], ++fins);
        } else if (count == 2 && forward != 1) {
            name(flipExamples, uses[b], ++flips);
        }
        b = e;
    }
    std::string w;
    // Most edges on a border: loose triangles, not a surface (a cloth mesh's border edges are
    // a few per cent of its edges; a triangle soup whose copies of a vertex differ by rounding,
    // 1e-7 m in a float export, is not welded by the automatic tolerance and falls apart).
    if (mesh.triangles.size() >= kLooseTriangles && 2 * borders > edges)
        w += std::to_string(borders) + " of " + std::to_string(edges) +
             " edges border a single triangle: the mesh is mostly loose triangles (the copies of "
             "a vertex the triangles share were not welded: are they apart by rounding?); the "
             "cloth falls apart along them: give a larger weld tolerance "
             "(MeshImportOptions::weldTolerance, a scene's \"weld_tolerance\")";
    if (fins > 0)
        w += std::string(w.empty() ? "" : "; ") + std::to_string(fins) +
             (fins == 1 ? " edge is" : " edges are") + " shared by more than two triangles (" +
             finExamples + (fins > 3 ? "; ..." : "") +
             "): the cloth simulates each edge as one spring, but a cloth is a surface with two "
             "sides (aerodynamics, self-collision); split the mesh there";
    if (flips > 0)
        w += std::string(w.empty() ? "" : "; ") + std::to_string(flips) +
             (flips == 1 ? " edge joins" : " edges join") +
             " two triangles wound against each other (" + flipExamples +
             (flips > 3 ? "; ..." : "") + "): the triangle normals flip across " +
             (flips == 1 ? "it" : "them") +
             " (the aerodynamic lift and the shading follow the normals); wind the triangles "
             "consistently";
    return w;
}

/// The length of an FBX file's unit in metres: its UnitScaleFactor (centimetres per unit; 1,
/// centimetres, when absent or not a positive finite number) over 100.
double fbxUnitInMetres(const aiScene& scene) {
    double factor = 1.0;
    if (scene.mMetaData) {
        float f = 0.0f;
        double d = 0.0;
        if (scene.mMetaData->Get("UnitScaleFactor", d))
            factor = d;
        else if (scene.mMetaData->Get("UnitScaleFactor", f))
            factor = double(f);
    }
    if (!(factor > 0.0) || !std::isfinite(factor)) factor = 1.0;
    return factor / 100.0;
}

/// A warning when the triangles make several separate pieces (empty for one): each moves on
/// its own. (A skirt whose panels' seam vertices were apart by more than the weld tolerance
/// fell apart at the seams with no word; a CAD export of 85 parts hung as 85 cloths.)
std::string piecesWarning(const TriangleMesh& mesh) {
    const std::size_t n = mesh.vertices.size();
    std::vector<Index> parent(n);
    for (std::size_t i = 0; i < n; ++i)
        parent[i] = static_cast<Index>(i);
    auto root = [&](Index i) {
        while (parent[i] != i)
            i = parent[i] = parent[parent[i]];
        return i;
    };
    for (const Triangle& t : mesh.triangles)
        for (int k = 1; k < 3; ++k)
            parent[root(t[k])] = root(t[0]);
    std::vector<std::size_t> size(n, 0);
    std::size_t pieces = 0, largest = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const Index r = root(static_cast<Index>(i));
        pieces += size[r] == 0;
        largest = std::max(largest, ++size[r]);
    }
    if (pieces <= 1) return {};
    return "the cloth is " + std::to_string(pieces) + " separate pieces (the largest has " +
           std::to_string(largest) + " of " + std::to_string(n) +
           " vertices), and each moves on its own; if they should hang together (a garment's "
           "panels, whose seam vertices do not meet), weld them with a larger weld tolerance "
           "(MeshImportOptions::weldTolerance, a scene's \"weld_tolerance\")";
}

/// A warning for a mesh too large to be a cloth in metres (empty otherwise): drape's unit is
/// the metre, and an export in millimetres or centimetres is 1000 or 100 times too large (a
/// review's CAD engine came in 743 m across, 530 t).
constexpr double kLargestLikelyCloth = 100.0; // [m] across

/// How a length in the program's unit is written: "m" in metres, else "units" (the
/// warnings say once which unit that is).
const char* unitLabel(double unitsPerMetre) {
    return unitsPerMetre == 1.0 ? "m" : "units";
}

std::string sizeWarning(const TriangleMesh& mesh, double unitsPerMetre) {
    if (mesh.vertices.empty()) return {};
    Vec3 lo = mesh.vertices[0], hi = mesh.vertices[0];
    for (const Vec3& p : mesh.vertices) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    const double across = (hi - lo).norm();
    if (!(across > kLargestLikelyCloth * unitsPerMetre)) return {};
    char buf[400];
    if (unitsPerMetre == 1.0)
        std::snprintf(buf, sizeof buf,
                      "the mesh is %.4g m across: drape's unit is the metre; if the file is in "
                      "millimetres or centimetres, scale it (MeshImportOptions::transform and "
                      "scale, a scene's mesh \"scale\": 0.001 or 0.01)",
                      across);
    else
        std::snprintf(buf, sizeof buf,
                      "the mesh is %.4g units across, %.4g m at %g units per metre "
                      "(a scene's units_per_metre); if the file is in a smaller unit, scale "
                      "it into the scene's (MeshImportOptions::transform and scale, a scene's "
                      "mesh \"scale\": the file's unit in scene units)",
                      across, across / unitsPerMetre, unitsPerMetre);
    return buf;
}

/// A warning for edges shorter than kShortEdge of the mesh's median edge (empty when none):
/// an edge is a spring, and the cloth's stable time step shrinks with its shortest, stiffest
/// spring (a 41 x 41 sheet with one sliver vertex 0.1 mm from a corner needs 77 sub-steps a
/// 60 Hz frame instead of 22, at 1e-7 m more than the 1000 allowed).
constexpr double kShortEdge = 0.01;
std::string shortEdgeWarning(const TriangleMesh& mesh, double unitsPerMetre) {
    const char* unit = unitLabel(unitsPerMetre);
    std::vector<std::pair<Index, Index>> edges;
    edges.reserve(3 * mesh.triangles.size());
    for (const Triangle& t : mesh.triangles)
        for (int k = 0; k < 3; ++k)
            edges.emplace_back(std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3]));
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    if (edges.empty()) return {};
    std::vector<double> length(edges.size());
    for (std::size_t e = 0; e < edges.size(); ++e)
        length[e] = (mesh.vertices[edges[e].second] - mesh.vertices[edges[e].first]).norm();
    std::vector<double> sorted = length;
    auto middle = sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2);
    std::nth_element(sorted.begin(), middle, sorted.end());
    const double median = *middle;
    std::size_t count = 0;
    double longestShort = 0.0;
    std::string examples;
    for (std::size_t e = 0; e < edges.size(); ++e) {
        if (!(length[e] < kShortEdge * median)) continue;
        longestShort = std::max(longestShort, length[e]);
        if (++count <= 3) {
            char buf[160];
            std::snprintf(buf, sizeof buf, "%svertices %u and %u, %.3g %s apart",
                          examples.empty() ? "" : "; ", unsigned(edges[e].first),
                          unsigned(edges[e].second), length[e], unit);
            examples += buf;
        }
    }
    if (count == 0) return {};
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "%zu edge%s shorter than %g %% of the median edge (%.3g %s): %s%s. Each is a "
                  "spring, and the cloth's stable time step shrinks with its shortest springs "
                  "(more automatic sub-steps, or an UnstableTimeStep error): weld such vertices "
                  "(a weld tolerance above %.3g %s) or remove the sliver triangles",
                  count, count == 1 ? "" : "s", 100.0 * kShortEdge, median, unit, examples.c_str(),
                  count > 3 ? "; ..." : "", longestShort, unit);
    return buf;
}

/// Runs f() on a thread with a kImportStackBytes stack and returns what it returns or throws
/// what it throws (falls back to this thread if no such thread can be made).
template <class F> auto onLargeStack(F f) -> decltype(f()) {
    using R = decltype(f());
    struct Job {
        F* f;
        std::optional<R> result;
        std::exception_ptr error;
    } job{&f, std::nullopt, nullptr};
    auto run = [](void* arg) -> void* {
        auto* j = static_cast<Job*>(arg);
        try {
            j->result.emplace((*j->f)());
        } catch (...) {
            j->error = std::current_exception();
        }
        return nullptr;
    };
    pthread_attr_t attr;
    pthread_t thread;
    const bool made = pthread_attr_init(&attr) == 0 &&
                      pthread_attr_setstacksize(&attr, kImportStackBytes) == 0 &&
                      pthread_create(&thread, &attr, run, &job) == 0;
    pthread_attr_destroy(&attr);
    if (!made) return f();
    pthread_join(thread, nullptr);
    if (job.error) std::rethrow_exception(job.error);
    return std::move(*job.result);
}

} // namespace

ImportedMesh importMesh(const std::filesystem::path& file, const MeshImportOptions& options) {
    return onLargeStack([&] { return importOnThisStack(file, options); });
}

namespace {

ImportedMesh importOnThisStack(const std::filesystem::path& file,
                               const MeshImportOptions& options) {
    if (!(options.unitsPerMetre >= 1e-6 && options.unitsPerMetre <= 1e6)) {
        char buf[120];
        std::snprintf(buf, sizeof buf,
                      "MeshImportOptions::unitsPerMetre must be in [1e-6, 1e6], got %g",
                      options.unitsPerMetre);
        meshFail(file, buf);
    }
    std::error_code ec;
    if (!std::filesystem::exists(file, ec)) meshFail(file, "mesh file not found");
    if (std::filesystem::is_directory(file, ec)) meshFail(file, "is a folder, not a mesh file");
    std::uint64_t size = 0;
    const std::string notRegular = detail::describeNonRegular(file.string(), size);
    if (!notRegular.empty()) meshFail(file, "cannot read: " + notRegular);
    if (size == 0) meshFail(file, "mesh file is empty");
    if (size > kMaxMeshFileBytes) meshFail(file, "mesh file larger than 512 MiB");

    if (isPlyWithoutEndHeader(file))
        meshFail(file, "PLY header has no end_header line (the file is truncated or not PLY)");
    if (isPlyWithTriangleStrips(file))
        meshFail(file, "PLY triangle strips (element tristrips) are not read correctly by the "
                       "mesh reader (assimp keeps one triangle of them): save the mesh with "
                       "faces (element face) instead");
    // assimp 5.2's 3MF reader aborts the process (free(): invalid pointer) on some files,
    // assimp's own test model among them (a review): no 3MF file is given to it.
    if (lowerExtension(file) == ".3mf")
        meshFail(file, "3MF files are not read (the mesh reader, assimp 5.2, crashes on some of "
                       "them): convert it to OBJ, PLY or glTF");
    checkHeaderCounts(file, lowerExtension(file), size);

    Assimp::Importer importer;
    // Every file assimp opens (the mesh file, material libraries, buffers, textures) goes
    // through drape's IO system: regular files only, none beyond 512 MiB, 2 GiB in all. The
    // importer owns it; `io` stays valid while the importer lives.
    auto* io = new detail::GuardedIOSystem(kMaxMeshFileBytes, kMaxImportBytes);
    importer.SetIOHandler(io);
    auto refusedFiles = [&] {
        std::string list;
        for (const auto& r : io->refusals())
            list += (list.empty() ? "" : "; ") + r.file + ": " + r.reason;
        return list;
    };
    // Points and lines stay in their meshes (they are skipped below) so that the order of
    // first use of every vertex is the file's order.
    const aiScene* scene = importer.ReadFile(file.string(), aiProcess_ValidateDataStructure);
    if (io->budgetExceeded())
        meshFail(file, "reading it and the files it names took more than " +
                           std::to_string(kMaxImportBytes >> 20) + " MiB");
    if (!scene || !scene->mRootNode) {
        std::string why = importer.GetErrorString();
        // assimp turns an allocation failure into its error string.
        if (why.find("bad_alloc") != std::string::npos ||
            why.find("length_error") != std::string::npos)
            why = "it runs out of memory (" + why +
                  "): a count in the file is larger than the file can hold";
        const std::string refused = refusedFiles();
        meshFail(file,
                 "assimp cannot read it: " + why +
                     (refused.empty() ? std::string() : " (refused to open " + refused + ")"));
    }
    ImportedMesh out;
    for (const auto& r : io->refusals())
        out.warnings.push_back(file.string() + ": did not open " + r.file +
                               ", which it names: " + r.reason + "; read without it");
    for (unsigned i = 0; i < scene->mNumMeshes; ++i) {
        const aiMesh& m = *scene->mMeshes[i];
        // Non-finite positions are named here: FindInvalidData (below) would delete the
        // whole mesh for one of them.
        for (unsigned v = 0; v < m.mNumVertices; ++v)
            if (!std::isfinite(m.mVertices[v].x) || !std::isfinite(m.mVertices[v].y) ||
                !std::isfinite(m.mVertices[v].z))
                meshFail(file, "vertex " + std::to_string(v) + " of mesh \"" + m.mName.C_Str() +
                                   "\" is not finite");
        // assimp 5.2's triangulation asserts (aborts the process) on a mesh that declares
        // polygons but has none, which some malformed files produce (a PLY polygon whose
        // indices are out of range is dropped after the mesh was marked): check before
        // triangulating.
        if (!(m.mPrimitiveTypes & aiPrimitiveType_POLYGON)) continue;
        bool polygon = false;
        for (unsigned f = 0; f < m.mNumFaces && !polygon; ++f)
            polygon = m.mFaces[f].mNumIndices > 3;
        if (!polygon)
            meshFail(file, "mesh \"" + std::string(m.mName.C_Str()) +
                               "\" declares polygons but has none (the file is malformed)");
    }
    scene = importer.ApplyPostProcessing(aiProcess_Triangulate);
    if (!scene || !scene->mRootNode)
        meshFail(file, std::string("assimp cannot triangulate it: ") + importer.GetErrorString());
    if (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE)
        meshFail(file, "assimp reports the file as incomplete");

    // assimp's FindDegenerates turns a triangle with two corners at one position into a line
    // or a point (it keeps every face where it is: AI_CONFIG_PP_FD_REMOVE off, and no
    // absolute area test, which would drop real millimetre triangles); FindInvalidData
    // deletes a mesh whose used vertices all sit at one point. Both are reported below.
    TriangleMasks wasTriangle;
    std::vector<std::string> meshNames(scene->mNumMeshes);
    std::vector<std::pair<const aiMesh*, std::size_t>> meshTriangles; // before the steps
    for (unsigned i = 0; i < scene->mNumMeshes; ++i) {
        const aiMesh* m = scene->mMeshes[i];
        auto& mask = wasTriangle[m];
        mask.resize(m->mNumFaces);
        std::size_t triangles = 0;
        for (unsigned f = 0; f < m->mNumFaces; ++f) {
            mask[f] = m->mFaces[f].mNumIndices == 3;
            triangles += mask[f];
        }
        meshNames[i] = m->mName.C_Str();
        meshTriangles.emplace_back(m, triangles);
    }
    importer.SetPropertyInteger(AI_CONFIG_PP_FD_REMOVE, 0);
    importer.SetPropertyInteger(AI_CONFIG_PP_FD_CHECKAREA, 0);
    scene = importer.ApplyPostProcessing(aiProcess_FindDegenerates | aiProcess_FindInvalidData);
    if (!scene || !scene->mRootNode) {
        const std::string why = importer.GetErrorString();
        if (why.find("No meshes remaining") != std::string::npos)
            meshFail(file, "contains no usable triangle: in every mesh all vertices sit at one "
                           "point");
        meshFail(file, "assimp cannot check it for degenerate triangles: " + why);
    }
    // Meshes FindInvalidData deleted (their pointers are gone from the scene).
    std::size_t collapsedMeshTriangles = 0;
    std::string collapsedMeshes;
    for (std::size_t i = 0; i < meshTriangles.size(); ++i) {
        bool present = false;
        for (unsigned j = 0; j < scene->mNumMeshes && !present; ++j)
            present = scene->mMeshes[j] == meshTriangles[i].first;
        if (present || meshTriangles[i].second == 0) continue;
        collapsedMeshTriangles += meshTriangles[i].second;
        collapsedMeshes +=
            (collapsedMeshes.empty() ? "" : ", ") +
            (meshNames[i].empty() ? "mesh " + std::to_string(i) : "mesh \"" + meshNames[i] + "\"");
    }
    // Mesh indices changed if a mesh was deleted: name meshes by the scene as it is now.
    std::vector<std::string> names(scene->mNumMeshes);
    for (unsigned i = 0; i < scene->mNumMeshes; ++i)
        names[i] = scene->mMeshes[i]->mName.C_Str();

    // An FBX file names its unit (UnitScaleFactor: centimetres per unit, 1 by default): read
    // in metres, as drape's coordinates are. (Without it, 4 of 5 FBX files a review tried came
    // in 100 times too large: a 1.7 m duck 166 m wide, a T-shirt of 1,126 kg. Collada's unit
    // assimp applies itself; its AI_CONFIG_FBX_CONVERT_TO_M left these files as they were.)
    aiMatrix4x4 unit;
    if (lowerExtension(file) == ".fbx") {
        const double metres = fbxUnitInMetres(*scene);
        const double u = options.unitsPerMetre;
        if (metres * u != 1.0) {
            aiMatrix4x4::Scaling(aiVector3D(ai_real(metres * u)), unit);
            char buf[240];
            if (u == 1.0)
                std::snprintf(buf, sizeof buf,
                              ": its unit is %g m (FBX UnitScaleFactor %g): read in metres", metres,
                              100.0 * metres);
            else
                std::snprintf(buf, sizeof buf,
                              ": its unit is %g m (FBX UnitScaleFactor %g): read in the "
                              "program's unit, %g per metre",
                              metres, 100.0 * metres, u);
            out.warnings.push_back(file.string() + buf);
        }
    }
    RawMesh raw;
    gather(*scene, *scene->mRootNode, unit, raw, wasTriangle, file);
    const std::size_t fileTriangles =
        raw.mesh.triangles.size() + raw.collapsed.size() + collapsedMeshTriangles;
    if (fileTriangles == 0)
        meshFail(file,
                 "contains no triangles" +
                     (raw.skipped ? " (only " + std::to_string(raw.skipped) + " points or lines)"
                                  : std::string()));

    if (options.transform) {
        transformMesh(raw.mesh, options.scale, options.rotationDeg, options.translation);
        for (std::size_t i = 0; i < raw.mesh.vertices.size(); ++i) {
            const Vec3& v = raw.mesh.vertices[i];
            if (!(v.cwiseAbs().maxCoeff() <= kMaxMeshCoordinate)) {
                char buf[128];
                std::snprintf(buf, sizeof buf, "(%g, %g, %g)", v.x(), v.y(), v.z());
                meshFail(file, "vertex " + std::to_string(i) + " lands at " + buf +
                                   " m after mesh.scale, rotation_deg and translation, outside "
                                   "the [-1e+06, 1e+06] m coordinate range");
            }
        }
    }

    // Welding and drape's own test: corners within the weld tolerance become one particle,
    // so a triangle can collapse here too, or keep a near-zero area (validateMesh's test),
    // or repeat another triangle's three particles.
    UnusableTriangles unusable;
    WeldResult welded;
    if (!raw.mesh.triangles.empty()) {
        const double tol = options.weldTolerance.value_or(automaticWeldTolerance(raw.mesh));
        try {
            welded = weldVertices(raw.mesh, tol);
            unusable = dropUnusableTriangles(welded.mesh, TopologyOptions{}.minAreaRatio);
        } catch (const drape::Error& e) {
            meshFail(file, e.what());
        }
    }
    std::vector<std::pair<unsigned, unsigned>> degenerate = raw.collapsed, duplicate;
    for (std::size_t t : unusable.degenerate)
        degenerate.push_back(raw.origin[t]);
    for (std::size_t t : unusable.duplicate)
        duplicate.push_back(raw.origin[t]);
    const std::size_t degenerateCount = degenerate.size() + collapsedMeshTriangles;

    // Drop vertices no triangle uses (point clouds, helper vertices, corners of dropped
    // triangles), keeping the order.
    std::vector<Index> used(welded.mesh.vertices.size(), 0);
    for (const Triangle& t : welded.mesh.triangles)
        for (Index i : t)
            used[i] = 1;
    std::vector<Index> compact(used.size(), Index(-1));
    for (std::size_t i = 0; i < used.size(); ++i)
        if (used[i]) {
            compact[i] = static_cast<Index>(out.mesh.vertices.size());
            out.mesh.vertices.push_back(welded.mesh.vertices[i]);
        }
    // Vertices no kept triangle uses (after welding: a seam's copies count once), and in an
    // OBJ file those nothing uses at all (assimp's reader drops them before we see them).
    const std::size_t isolated = welded.mesh.vertices.size() - out.mesh.vertices.size() +
                                 (lowerExtension(file) == ".obj" ? unusedObjVertices(file) : 0);

    if (degenerateCount + duplicate.size() + isolated > 0) {
        std::string what;
        if (degenerateCount > 0) {
            what += std::to_string(degenerateCount) + " degenerate triangle" +
                    (degenerateCount == 1 ? "" : "s") + " (two corners at one point, or no area";
            if (!degenerate.empty()) what += ": " + whereText(degenerate, names);
            if (!collapsedMeshes.empty())
                what += (degenerate.empty() ? ": " : "; ") + std::string("all of ") +
                        collapsedMeshes + ", whose vertices all sit at one point";
            what += ")";
        }
        if (!duplicate.empty())
            what += (what.empty() ? "" : ", ") + std::to_string(duplicate.size()) +
                    " duplicate triangle" + (duplicate.size() == 1 ? "" : "s") +
                    " (the same three corners as an earlier one: " + whereText(duplicate, names) +
                    ")";
        if (isolated > 0)
            what += (what.empty() ? "" : ", ") + std::to_string(isolated) +
                    (isolated == 1 ? " vertex" : " vertices") + " no triangle uses";
        if (options.refuseDegenerate)
            throw Error(ErrorCode::DegenerateTriangle,
                        file.string() + ": has " + what +
                            "; refused (MeshImportOptions::refuseDegenerate, a scene's mesh "
                            "\"degenerate_triangles\": \"refuse\"; left off, \"drop\", they "
                            "are dropped with a warning)");
        if (out.mesh.vertices.empty() || welded.mesh.triangles.empty())
            meshFail(file, "contains no usable triangle: all " + std::to_string(fileTriangles) +
                               " are degenerate or duplicates (" + what + ")");
        out.warnings.push_back(file.string() + ": dropped " + what + "; " +
                               std::to_string(welded.mesh.triangles.size()) + " of " +
                               std::to_string(fileTriangles) + " triangles kept");
    }
    if (out.mesh.vertices.size() > kMaxMeshVertices)
        meshFail(file, std::to_string(out.mesh.vertices.size()) +
                           " vertices after welding exceeds the limit of " +
                           std::to_string(kMaxMeshVertices));
    out.mesh.triangles.reserve(welded.mesh.triangles.size());
    for (const Triangle& t : welded.mesh.triangles)
        out.mesh.triangles.push_back({compact[t[0]], compact[t[1]], compact[t[2]]});
    for (const auto& [name, rawIdx] : raw.rawGroups) {
        std::vector<Index> g;
        std::vector<unsigned char> seen(out.mesh.vertices.size(), 0);
        for (Index r : rawIdx) {
            const Index w = compact[welded.remap[r]];
            if (w == Index(-1) || seen[w]) continue;
            seen[w] = 1;
            g.push_back(w);
        }
        if (!g.empty()) out.groups[name] = std::move(g);
    }
    if (raw.skipped > 0)
        out.warnings.push_back(file.string() + ": skipped " + std::to_string(raw.skipped) +
                               (raw.skipped == 1 ? " point or line" : " points or lines") +
                               " (a cloth is made of the file's triangles only)");
    if (const std::string w = shortEdgeWarning(out.mesh, options.unitsPerMetre); !w.empty())
        out.warnings.push_back(file.string() + ": " + w);
    if (const std::string w = surfaceWarning(out.mesh); !w.empty())
        out.warnings.push_back(file.string() + ": " + w);
    if (options.cloth) {
        if (const std::string w = piecesWarning(out.mesh); !w.empty())
            out.warnings.push_back(file.string() + ": " + w);
        if (const std::string w = sizeWarning(out.mesh, options.unitsPerMetre); !w.empty())
            out.warnings.push_back(file.string() + ": " + w);
    }
    out.rawVertexCount = raw.mesh.vertices.size();
    out.skippedPrimitives = raw.skipped;
    out.droppedDegenerate = degenerateCount;
    out.droppedDuplicates = duplicate.size();
    out.droppedVertices = isolated;
    return out;
}

} // namespace

void exportMesh(const TriangleMesh& mesh, const std::filesystem::path& file) {
    const std::string ext = lowerExtension(file);
    const char* format = nullptr;
    if (ext == ".obj")
        format = "objnomtl";
    else if (ext == ".ply")
        format = "ply";
    else if (ext == ".gltf")
        format = "gltf2";
    else if (ext == ".glb")
        format = "glb2";
    // STL and 3DS are left out: STL has no shared vertices and assimp's 3DS writer splits
    // them, so neither could keep vertex i of the cloth as vertex i of the file.
    else
        meshFail(file,
                 "unknown mesh format \"" + ext + "\" for export (use .obj, .ply, .gltf or .glb)");
    if (mesh.vertices.empty() || mesh.triangles.empty()) meshFail(file, "nothing to export");
    // The file stores single precision: a vertex beyond its range would be written as inf.
    constexpr double kFloatMax = static_cast<double>(std::numeric_limits<float>::max());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
        if (!(mesh.vertices[i].cwiseAbs().maxCoeff() <= kFloatMax))
            meshFail(file, "vertex " + std::to_string(i) +
                               " is not finite or beyond the "
                               "single-precision range of the file; nothing written");

    // Area-weighted vertex normals, so that other tools shade the mesh smoothly.
    std::vector<Vec3> normals(mesh.vertices.size(), Vec3::Zero());
    for (const Triangle& t : mesh.triangles) {
        if (t[0] >= mesh.vertices.size() || t[1] >= mesh.vertices.size() ||
            t[2] >= mesh.vertices.size())
            meshFail(file, "triangle index out of range");
        const Vec3 n = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                           .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
        for (Index i : t)
            normals[i] += n;
    }

    aiScene scene;
    scene.mRootNode = new aiNode("cloth");
    scene.mNumMaterials = 1;
    scene.mMaterials = new aiMaterial* [1] { new aiMaterial() };
    scene.mNumMeshes = 1;
    scene.mMeshes = new aiMesh* [1] { new aiMesh() };
    scene.mRootNode->mNumMeshes = 1;
    scene.mRootNode->mMeshes = new unsigned[1]{0};
    aiMesh& m = *scene.mMeshes[0];
    m.mName = aiString("cloth");
    m.mMaterialIndex = 0;
    m.mNumVertices = static_cast<unsigned>(mesh.vertices.size());
    m.mVertices = new aiVector3D[m.mNumVertices];
    m.mNormals = new aiVector3D[m.mNumVertices];
    for (unsigned i = 0; i < m.mNumVertices; ++i) {
        const Vec3& v = mesh.vertices[i];
        const Vec3 n = normals[i].norm() > 0.0 ? Vec3(normals[i].normalized()) : Vec3::UnitY();
        m.mVertices[i] = aiVector3D(static_cast<ai_real>(v.x()), static_cast<ai_real>(v.y()),
                                    static_cast<ai_real>(v.z()));
        m.mNormals[i] = aiVector3D(static_cast<ai_real>(n.x()), static_cast<ai_real>(n.y()),
                                   static_cast<ai_real>(n.z()));
    }
    // assimp's OBJ writer numbers vertices in the order faces first use them. One point
    // primitive per vertex, written before the triangles, makes that order the particle
    // order ("p i" lines; importMesh skips points but keeps the order).
    const bool pointPrefix = ext == ".obj";
    const std::size_t pointFaces = pointPrefix ? mesh.vertices.size() : 0;
    m.mNumFaces = static_cast<unsigned>(pointFaces + mesh.triangles.size());
    m.mFaces = new aiFace[m.mNumFaces];
    for (std::size_t i = 0; i < pointFaces; ++i) {
        m.mFaces[i].mNumIndices = 1;
        m.mFaces[i].mIndices = new unsigned[1]{static_cast<unsigned>(i)};
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        aiFace& f = m.mFaces[pointFaces + t];
        f.mNumIndices = 3;
        f.mIndices =
            new unsigned[3]{mesh.triangles[t][0], mesh.triangles[t][1], mesh.triangles[t][2]};
    }
    m.mPrimitiveTypes = static_cast<unsigned>(aiPrimitiveType_TRIANGLE) |
                        (pointPrefix ? static_cast<unsigned>(aiPrimitiveType_POINT) : 0u);

    Assimp::Exporter exporter;
    const aiExportDataBlob* blob = exporter.ExportToBlob(&scene, format);
    if (!blob) meshFail(file, std::string("assimp cannot write it: ") + exporter.GetErrorString());
    if (blob->next) { // a format of several files (.gltf and its .bin): assimp names them
        if (exporter.Export(&scene, format, file.string()) != AI_SUCCESS)
            meshFail(file, std::string("assimp cannot write it: ") + exporter.GetErrorString());
        return;
    }
    // One file: written here, so that a failed write (a full disk) is an error, not a
    // truncated file (assimp's own file writer does not check its writes).
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    if (!out) meshFail(file, "cannot open it for writing: " + std::string(std::strerror(errno)));
    out.write(static_cast<const char*>(blob->data), static_cast<std::streamsize>(blob->size));
    out.close();
    if (!out)
        meshFail(file, "writing it failed (disk full?): " + std::string(std::strerror(errno)));
}

#else // no assimp

bool available() {
    return false;
}

ImportedMesh importMesh(const std::filesystem::path& file, const MeshImportOptions&) {
    meshFail(file,
             "this build has no mesh import (drape was configured with -DDRAPE_WITH_ASSIMP=OFF)");
}

void exportMesh(const TriangleMesh&, const std::filesystem::path& file) {
    meshFail(file,
             "this build has no mesh export (drape was configured with -DDRAPE_WITH_ASSIMP=OFF)");
}

#endif

} // namespace drape::io
