// Snapshot save/restore and state hashing (format in snapshot.hpp).
#include "drape/snapshot.hpp"

#include "drape/error.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

#if defined(_WIN32)
#include <filesystem>
#else
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#endif

namespace drape {
namespace {

constexpr char kMagic[8] = {'D', 'R', 'A', 'P', 'E', 'S', 'N', 'P'};
// 2: the limiter's warm start per spring; 3: sleep state and the caller stages' states;
// 4: the carried aerodynamics; 5: the over-bound flag (ClothState::overBound); 6: the strain
// bound the state was stepped under (ClothState::bound).
constexpr std::uint32_t kVersion = 6;
constexpr std::uint32_t kOldestVersion = 2;
/// Caps on the variable part, so a corrupt length fails cleanly instead of allocating.
constexpr std::uint32_t kMaxStages = 1024;
constexpr std::uint32_t kMaxStageName = 4096;

struct Fnv {
    std::uint64_t h = 1469598103934665603ull;
    void bytes(const void* data, std::size_t n) {
        const auto* p = static_cast<const unsigned char*>(data);
        for (std::size_t i = 0; i < n; ++i) {
            h ^= p[i];
            h *= 1099511628211ull;
        }
    }
    template <class T> void pod(const T& v) { bytes(&v, sizeof(T)); }
};

class Writer {
  public:
    template <class T> void pod(const T& v) {
        const auto* p = reinterpret_cast<const unsigned char*>(&v);
        out.insert(out.end(), p, p + sizeof(T));
    }
    void bytes(const void* data, std::size_t n) {
        const auto* p = static_cast<const unsigned char*>(data);
        out.insert(out.end(), p, p + n);
    }
    /// An optional per-particle list: u8 1 and 3 f64 per particle when it holds n entries,
    /// else u8 0.
    void optionalList(const Vec3List& list, std::size_t n) {
        const bool present = list.size() == n;
        pod(static_cast<std::uint8_t>(present ? 1 : 0));
        if (present)
            for (const Vec3& a : list)
                bytes(a.data(), 3 * sizeof(double));
    }
    std::vector<unsigned char> out;
};

class Reader {
  public:
    explicit Reader(const std::vector<unsigned char>& b) : bytes(b), end(b.size()) {}
    template <class T> T pod(const char* what) {
        if (pos + sizeof(T) > end) {
            throw Error(ErrorCode::InvalidArgument,
                        std::string("snapshot is truncated (ends inside ") + what + ")");
        }
        T v;
        std::memcpy(&v, bytes.data() + pos, sizeof(T));
        pos += sizeof(T);
        return v;
    }
    /// The next n bytes (n checked against what is left before anything is allocated).
    std::vector<unsigned char> take(std::uint64_t n, const char* what) {
        if (n > end - pos) {
            throw Error(ErrorCode::InvalidArgument,
                        std::string("snapshot is truncated (ends inside ") + what + ")");
        }
        std::vector<unsigned char> out(bytes.begin() + std::ptrdiff_t(pos),
                                       bytes.begin() + std::ptrdiff_t(pos + n));
        pos += std::size_t(n);
        return out;
    }
    /// What Writer::optionalList wrote for n particles (empty when absent).
    Vec3List optionalList(std::size_t n, const char* flag, const char* what) {
        Vec3List list;
        if (pod<std::uint8_t>(flag) == 0) return list;
        const auto raw = take(std::uint64_t(n) * 3 * sizeof(double), what);
        list.resize(n);
        std::memcpy(static_cast<void*>(list.data()), raw.data(), raw.size());
        return list;
    }
    const std::vector<unsigned char>& bytes;
    std::size_t pos = 0;
    std::size_t end; ///< where the data ends (the checksum starts)
};

/// The bytes of a snapshot file, by the rule drape::io applies to mesh files: a regular file
/// only (a folder, a FIFO or a device such as /dev/zero is refused by name, without blocking
/// or reading it), of at most kMaxSnapshotFileBytes, read up to the size it had when opened.
std::vector<unsigned char> readSnapshotFile(const std::string& path) {
    auto fail = [&path](const std::string& why, const char* verb = "read") {
        throw Error(ErrorCode::InvalidArgument,
                    std::string("cannot ") + verb + " snapshot file '" + path + "': " + why +
                        "; give the path of a snapshot written by saveSnapshotFile");
    };
    auto checkSize = [&](std::uint64_t size) {
        if (size > kMaxSnapshotFileBytes)
            fail("it is " + std::to_string(size) + " bytes, more than the limit of " +
                 std::to_string(kMaxSnapshotFileBytes >> 20) + " MiB (kMaxSnapshotFileBytes)");
    };
    std::vector<unsigned char> bytes;
#if defined(_WIN32)
    std::error_code ec;
    const std::filesystem::path file(path);
    if (!std::filesystem::exists(file, ec)) fail("no such file", "open");
    if (std::filesystem::is_directory(file, ec)) fail("it is a folder, not a file");
    if (!std::filesystem::is_regular_file(file, ec)) fail("it is not a regular file");
    const std::uint64_t size = std::filesystem::file_size(file, ec);
    if (ec) fail(ec.message());
    checkSize(size);
    std::ifstream in(path, std::ios::binary);
    if (!in) fail("it cannot be opened", "open");
    bytes.resize(static_cast<std::size_t>(size));
    in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size));
    bytes.resize(static_cast<std::size_t>(in.gcount()));
#else
    // O_NONBLOCK: opening a FIFO returns at once (a blocking open waits for a writer); fstat
    // then tells what the path is.
    const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
    if (fd < 0) fail(std::strerror(errno), "open");
    struct Closer {
        int fd;
        ~Closer() { ::close(fd); }
    } closer{fd};
    struct stat st {};
    if (::fstat(fd, &st) != 0) fail(std::strerror(errno));
    if (S_ISDIR(st.st_mode)) fail("it is a folder, not a file");
    if (S_ISFIFO(st.st_mode)) fail("it is a FIFO, not a regular file");
    if (S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode)) fail("it is a device, not a regular file");
    if (!S_ISREG(st.st_mode)) fail("it is not a regular file");
    const std::uint64_t size = static_cast<std::uint64_t>(st.st_size);
    checkSize(size);
    bytes.resize(static_cast<std::size_t>(size));
    std::size_t got = 0;
    while (got < bytes.size()) { // never past the size it had when opened
        const ssize_t n = ::read(fd, bytes.data() + got, bytes.size() - got);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) fail(std::strerror(errno));
        if (n == 0) break; // the file shrank: loadSnapshot reports it truncated
        got += static_cast<std::size_t>(n);
    }
    bytes.resize(got);
#endif
    return bytes;
}

} // namespace

std::uint64_t stateHash(const Cloth& cloth) {
    Fnv f;
    for (const auto& x : cloth.positions())
        f.bytes(x.data(), 3 * sizeof(double));
    for (const auto& v : cloth.velocities())
        f.bytes(v.data(), 3 * sizeof(double));
    return f.h;
}

std::uint64_t topologyFingerprint(const ClothTopology& topology) {
    Fnv f;
    const std::uint64_t n = topology.particleCount(), t = topology.triangleCount();
    f.pod(n);
    f.pod(t);
    for (const auto& x : topology.restPositions())
        f.bytes(x.data(), 3 * sizeof(double));
    for (const auto& tri : topology.triangles())
        f.bytes(tri.data(), 3 * sizeof(Index));
    return f.h;
}

std::vector<unsigned char> saveSnapshot(const Cloth& cloth) {
    // The writer reads particleCount() entries of each: a vector the caller resized through
    // mutablePositions() or mutableVelocities() is refused by name.
    const std::size_t n = cloth.particleCount();
    auto checkSize = [n](std::size_t got, const char* what, const char* access) {
        if (got == n) return;
        throw Error(ErrorCode::InvalidArgument,
                    std::string("saveSnapshot: the ") + what + " hold " + std::to_string(got) +
                        " entries but the cloth has " + std::to_string(n) +
                        " particles (the vector returned by " + access +
                        " was resized); change its values, not its size: resize it back to "
                        "particleCount() entries");
    };
    checkSize(cloth.positions().size(), "positions", "mutablePositions()");
    checkSize(cloth.velocities().size(), "velocities", "mutableVelocities()");
    Writer w;
    for (char c : kMagic)
        w.pod(c);
    w.pod(kVersion);
    w.pod(topologyFingerprint(cloth.topology()));
    w.pod(static_cast<std::uint64_t>(cloth.particleCount()));
    const ClothState& st = cloth.state();
    w.pod(st.time);
    w.pod(static_cast<std::uint64_t>(st.steps));
    w.pod(static_cast<std::uint8_t>(st.forcesValid ? 1 : 0));
    for (std::size_t i = 0; i < cloth.particleCount(); ++i) {
        for (const Vec3* v : {&st.x[i], &st.v[i], &st.f[i]})
            for (int c = 0; c < 3; ++c)
                w.pod((*v)[c]);
        w.pod(static_cast<std::uint8_t>(st.pinned[i]));
    }
    // The limiter's warm start: one value per spring (0 where it has none yet).
    const auto& lambda = cloth.limiter().warmStartState();
    for (std::size_t s = 0; s < cloth.topology().springCount(); ++s)
        w.pod(s < lambda.size() ? lambda[s] : 0.0);
    // Sleep: asleep, the quiet time, and the positions the quiet time is measured from.
    w.pod(static_cast<std::uint8_t>(st.asleep ? 1 : 0));
    w.pod(st.quietTime);
    w.optionalList(st.anchor, cloth.particleCount());
    // Version 4: the aerodynamic forces the next opening kick takes (ClothState::aero).
    w.optionalList(st.aero, cloth.particleCount());
    // Version 5: the last step's limiter left springs beyond the bound (ClothState::overBound).
    w.pod(static_cast<std::uint8_t>(st.overBound ? 1 : 0));
    // Version 6: the strain bound the state was stepped under (ClothState::bound).
    w.pod(st.bound);
    // The caller stages' states, by name (ClothStage::saveState).
    w.pod(static_cast<std::uint32_t>(cloth.stages().size()));
    for (const auto& stage : cloth.stages()) {
        const std::string name = stage->name();
        const std::vector<unsigned char> state = stage->saveState();
        w.pod(static_cast<std::uint32_t>(name.size()));
        w.bytes(name.data(), name.size());
        w.pod(static_cast<std::uint64_t>(state.size()));
        w.bytes(state.data(), state.size());
    }
    Fnv sum;
    sum.bytes(w.out.data(), w.out.size());
    w.pod(sum.h);
    return std::move(w.out);
}

void loadSnapshot(Cloth& cloth, const std::vector<unsigned char>& bytes) {
    // Replacing the state mid-step would leave the step's other half on another state (and the
    // stages' states would be loaded while they run): refused before anything is read.
    if (cloth.inStep())
        throw Error(ErrorCode::InvalidArgument,
                    "loadSnapshot: not allowed during the cloth's own step (from a stage); a "
                    "stage runs once per step with the step's dt: load the snapshot before or "
                    "after the step");
    if (bytes.size() < sizeof(kMagic) || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
        throw Error(ErrorCode::InvalidArgument, "not a drape snapshot (bad magic bytes)");
    }
    if (bytes.size() < sizeof(kMagic) + 8) {
        throw Error(ErrorCode::InvalidArgument, "snapshot is truncated (no checksum)");
    }
    Fnv sum;
    sum.bytes(bytes.data(), bytes.size() - 8);
    std::uint64_t stored;
    std::memcpy(&stored, bytes.data() + bytes.size() - 8, 8);
    Reader r(bytes);
    r.pos = sizeof(kMagic);
    r.end = bytes.size() - 8;
    const auto version = r.pod<std::uint32_t>("the version");
    if (version < kOldestVersion || version > kVersion) {
        throw Error(ErrorCode::InvalidArgument,
                    "snapshot version " + std::to_string(version) + " is not supported (expected " +
                        std::to_string(kOldestVersion) + " to " + std::to_string(kVersion) + ")");
    }
    const auto fingerprint = r.pod<std::uint64_t>("the topology fingerprint");
    const auto n = r.pod<std::uint64_t>("the particle count");
    if (n != cloth.particleCount()) {
        throw Error(ErrorCode::InvalidArgument, "snapshot has " + std::to_string(n) +
                                                    " particles but the cloth has " +
                                                    std::to_string(cloth.particleCount()));
    }
    const std::size_t ns = cloth.topology().springCount();
    // The fixed part (version 2 is only that); version 3 has a variable part after it.
    const std::size_t fixed = sizeof(kMagic) + 4 + 8 + 8 + 8 + 8 + 1 + n * (9 * 8 + 1) + ns * 8 + 8;
    const std::size_t expected = version == 2 ? fixed
                                              : fixed + 1 + 8 + 1 + 4 + (version >= 4 ? 1 : 0) +
                                                    (version >= 5 ? 1 : 0) + (version >= 6 ? 8 : 0);
    if (version == 2 ? bytes.size() != expected : bytes.size() < expected) {
        throw Error(ErrorCode::InvalidArgument,
                    "snapshot is " + std::to_string(bytes.size()) + " bytes, expected " +
                        std::to_string(expected) + (bytes.size() < expected ? " (truncated)" : ""));
    }
    if (stored != sum.h) {
        throw Error(ErrorCode::InvalidArgument, "snapshot checksum mismatch (the file is corrupt)");
    }
    if (fingerprint != topologyFingerprint(cloth.topology())) {
        throw Error(ErrorCode::InvalidArgument,
                    "snapshot was saved from a cloth with a different topology");
    }
    const double time = r.pod<double>("the time");
    const auto steps = r.pod<std::uint64_t>("the step count");
    const auto valid = r.pod<std::uint8_t>("the force flag");
    Vec3List x(n), v(n), f(n);
    std::vector<unsigned char> pinned(n);
    for (std::size_t i = 0; i < n; ++i) {
        for (Vec3* dst : {&x[i], &v[i], &f[i]})
            for (int c = 0; c < 3; ++c)
                (*dst)[c] = r.pod<double>("the particle data");
        pinned[i] = r.pod<std::uint8_t>("the pin flags");
    }
    std::vector<double> lambda(ns);
    for (std::size_t s = 0; s < ns; ++s)
        lambda[s] = r.pod<double>("the limiter's warm start");
    bool asleep = false;
    double quietTime = 0.0;
    bool overBound = false;
    double bound = std::numeric_limits<double>::quiet_NaN(); // not known before version 6
    Vec3List anchor, aero;
    std::vector<std::pair<std::string, std::vector<unsigned char>>> stageStates;
    if (version >= 3) {
        asleep = r.pod<std::uint8_t>("the sleep flag") != 0;
        quietTime = r.pod<double>("the quiet time");
        anchor = r.optionalList(n, "the anchor flag", "the sleep anchors");
        if (version >= 4) aero = r.optionalList(n, "the aerodynamics flag", "the aerodynamics");
        if (version >= 5) {
            const auto flag = r.pod<std::uint8_t>("the over-bound flag");
            if (flag > 1)
                throw Error(ErrorCode::InvalidArgument, "snapshot's over-bound flag is " +
                                                            std::to_string(flag) +
                                                            " (expected 0 or 1)");
            overBound = flag != 0;
        }
        if (version >= 6) {
            bound = r.pod<double>("the strain bound");
            if (!(bound >= 0.0))
                throw Error(ErrorCode::InvalidArgument,
                            "snapshot's strain bound is " + std::to_string(bound) +
                                " (expected >= 0, infinity without the limiter)");
        }
        const auto count = r.pod<std::uint32_t>("the stage count");
        if (count > kMaxStages)
            throw Error(ErrorCode::InvalidArgument,
                        "snapshot claims " + std::to_string(count) + " stages");
        for (std::uint32_t k = 0; k < count; ++k) {
            const auto length = r.pod<std::uint32_t>("a stage name");
            if (length > kMaxStageName)
                throw Error(ErrorCode::InvalidArgument,
                            "snapshot holds a stage name of " + std::to_string(length) + " bytes");
            const auto name = r.take(length, "a stage name");
            const auto size = r.pod<std::uint64_t>("a stage state");
            stageStates.emplace_back(std::string(name.begin(), name.end()),
                                     r.take(size, "a stage state"));
        }
        if (r.pos != r.end)
            throw Error(ErrorCode::InvalidArgument,
                        "snapshot has " + std::to_string(r.end - r.pos) + " bytes after its end");
    }
    // The cloth's state, checked before anything changes (Cloth::checkState). An older
    // snapshot holds no sleep: the cloth is awake and its quiet count restarts.
    ClothState st;
    st.x = std::move(x);
    st.v = std::move(v);
    st.f = std::move(f);
    st.forcesValid = valid != 0;
    st.pinned = std::move(pinned);
    st.time = time;
    st.steps = steps;
    if (version >= 3) {
        st.asleep = asleep;
        st.quietTime = quietTime;
        st.anchor = std::move(anchor);
        st.aero = std::move(aero);
        st.overBound = overBound;
        st.bound = bound;
    }
    cloth.checkState(st, lambda);
    // The stages take their states first: a stage that refuses its bytes throws before the
    // cloth changes. A stage of this cloth the snapshot does not name starts afresh (empty
    // state); a state whose stage this cloth lacks is ignored (a snapshot taken in a world
    // loads into a bare cloth). Stages of one name are matched in order.
    std::vector<bool> used(stageStates.size(), false);
    for (const auto& stage : cloth.stages()) {
        const std::string name = stage->name();
        std::vector<unsigned char> state;
        for (std::size_t k = 0; k < stageStates.size(); ++k) {
            if (used[k] || stageStates[k].first != name) continue;
            used[k] = true;
            state = std::move(stageStates[k].second);
            break;
        }
        try {
            stage->loadState(state);
        } catch (const Error& e) {
            throw Error(e.code(), "snapshot state of stage '" + name + "': " + e.what());
        }
    }
    // Commit: nothing above modified the cloth's own state.
    cloth.restoreState(std::move(st), std::move(lambda));
}

void saveSnapshotFile(const Cloth& cloth, const std::string& path) {
    const auto bytes = saveSnapshot(cloth);
    std::ofstream out(path, std::ios::binary);
    if (!out)
        throw Error(ErrorCode::InvalidArgument,
                    "cannot open snapshot file '" + path + "' for writing");
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
    if (!out)
        throw Error(ErrorCode::InvalidArgument, "failed writing snapshot file '" + path + "'");
}

void loadSnapshotFile(Cloth& cloth, const std::string& path) {
    const std::vector<unsigned char> bytes = readSnapshotFile(path);
    try {
        loadSnapshot(cloth, bytes);
    } catch (const Error& e) {
        throw Error(e.code(), "snapshot file '" + path + "': " + e.what());
    }
}

} // namespace drape
