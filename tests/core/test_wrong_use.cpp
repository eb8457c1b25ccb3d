// Wrong use of a cloth's API gets a drape::Error that names the problem and the fix, never a
// crash, a hang or a silent NaN: resized state vectors, calls from inside the cloth's own step,
// snapshot files that are not regular files, values out of an enum's range.
#include "helpers.hpp"

#include "drape/cloth.hpp"
#include "drape/executor.hpp"
#include "drape/snapshot.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <future>
#include <limits>
#include <memory>
#include <thread>

#if !defined(_WIN32)
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#endif

using namespace drape;
using namespace drape_test;

namespace {

constexpr double kDt = 1.0 / 60.0;

std::unique_ptr<Cloth> smallSheet(const ClothSettings& s = {}) {
    SheetSpec spec;
    spec.rows = 6;
    spec.cols = 6;
    spec.spacing = 0.1;
    return std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), s);
}

} // namespace

TEST_CASE("Resized positions or velocities are refused by step and saveSnapshot, by name",
          "[errors][wrong-use]") {
    auto c = smallSheet();
    c->step(kDt);
    const std::size_t n = c->particleCount();
    REQUIRE(n == 36);

    SECTION("positions shrunk, cleared or grown") {
        const Vec3List keep = c->positions();
        for (std::size_t size : {std::size_t(3), std::size_t(0), std::size_t(200)}) {
            c->mutablePositions().resize(size, Vec3::Zero());
            CHECK(c->particleCount() == n);
            REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, "positions");
            REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, "mutablePositions()");
            REQUIRE_DRAPE_ERROR(c->stepPart(kDt, 2), ErrorCode::InvalidArgument, "resize it back");
            REQUIRE_DRAPE_ERROR(saveSnapshot(*c), ErrorCode::InvalidArgument, "positions");
            // The diagnostics read by particle and spring end: refused, not read past the end
            // (springEnergy read freed memory after a shrink, maxStrain returned inf).
            REQUIRE_DRAPE_ERROR(c->maxStrain(), ErrorCode::InvalidArgument, "Cloth::maxStrain");
            REQUIRE_DRAPE_ERROR(c->meanStrain(), ErrorCode::InvalidArgument, "positions");
            REQUIRE_DRAPE_ERROR(c->springEnergy(), ErrorCode::InvalidArgument, "positions");
            REQUIRE_DRAPE_ERROR(c->gravityEnergy(), ErrorCode::InvalidArgument, "positions");
            c->mutablePositions() = keep;
        }
        CHECK(std::isfinite(c->maxStrain()));
    }
    SECTION("velocities shrunk or grown") {
        const Vec3List keep = c->velocities();
        for (std::size_t size : {std::size_t(3), std::size_t(0), std::size_t(200)}) {
            c->mutableVelocities().resize(size, Vec3::Zero());
            REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, "mutableVelocities()");
            REQUIRE_DRAPE_ERROR(saveSnapshot(*c), ErrorCode::InvalidArgument, "velocities");
            REQUIRE_DRAPE_ERROR(c->kineticEnergy(), ErrorCode::InvalidArgument, "velocities");
            REQUIRE_DRAPE_ERROR(c->momentum(), ErrorCode::InvalidArgument, "Cloth::momentum");
            c->mutableVelocities() = keep;
        }
    }
    SECTION("a stage that resizes them fails the step, which is then undone") {
        struct Resizer : ClothStage {
            bool on = true;
            std::string name() const override { return "resizer"; }
            void run(Cloth& cloth, double) override {
                if (on) cloth.mutablePositions().resize(3);
            }
        };
        auto stage = std::make_shared<Resizer>();
        c->addStage(stage);
        const std::uint64_t before = stateHash(*c);
        REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, "stage 'resizer'");
        CHECK(c->positions().size() == n);
        CHECK(stateHash(*c) == before);
        stage->on = false;
    }
    // Once the size is back, the cloth steps and saves as before.
    for (int k = 0; k < 3; ++k)
        c->step(kDt);
    CHECK(c->stepCount() == 4);
    for (const Vec3& x : c->positions())
        CHECK(x.allFinite());
    auto copy = smallSheet();
    loadSnapshot(*copy, saveSnapshot(*c));
    CHECK(stateHash(*copy) == stateHash(*c));
}

namespace {

/// A stage that runs a function of the cloth.
struct FnStage : ClothStage {
    explicit FnStage(std::string n, std::function<void(Cloth&)> f)
        : label(std::move(n)), fn(std::move(f)) {}
    std::string name() const override { return label; }
    void run(Cloth& cloth, double) override {
        ++runs;
        if (fn) fn(cloth);
    }
    std::string label;
    std::function<void(Cloth&)> fn;
    int runs = 0;
};

} // namespace

TEST_CASE("Calls that replace the state are refused from inside the cloth's own step",
          "[errors][wrong-use][stages]") {
    auto c = smallSheet();
    c->step(kDt);
    const auto saved = saveSnapshot(*c);
    const ClothState state = c->state();
    const std::vector<double> warm(c->limiter().warmStartState().begin(),
                                   c->limiter().warmStartState().end());
    int attempt = 0;
    auto stage = std::make_shared<FnStage>("reentrant", [&](Cloth& cloth) {
        CHECK(cloth.inStep());
        if (attempt == 1) cloth.step(kDt / 10); // used to recurse until the stack overflowed
        if (attempt == 2) cloth.stepPart(kDt / 10, 2);
        if (attempt == 3) loadSnapshot(cloth, saved); // used to be accepted mid-step
        if (attempt == 4) cloth.restoreState(state, warm);
        if (attempt == 5) cloth.setExecutor(nullptr);
    });
    c->addStage(stage);
    const char* names[] = {
        "", "Cloth::step", "Cloth::step", "loadSnapshot", "restoreState", "setExecutor"};
    for (attempt = 1; attempt <= 5; ++attempt) {
        INFO("attempt " << attempt);
        const std::uint64_t before = stateHash(*c);
        const std::uint64_t steps = c->stepCount();
        REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, names[attempt]);
        REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument,
                            "not allowed during the cloth's own step (from a stage)");
        // The failed step is undone, and the cloth steps on once the stage behaves.
        CHECK(stateHash(*c) == before);
        CHECK(c->stepCount() == steps);
        CHECK_FALSE(c->inStep());
    }
    attempt = 0;
    c->step(kDt);
    CHECK(c->stepCount() == 2);
    CHECK_FALSE(c->inStep());
    // Outside a step the same calls are fine.
    loadSnapshot(*c, saved);
    CHECK(c->stepCount() == 1);
    c->restoreState(state, warm);
}

TEST_CASE("A stage that removes itself during the step does not make the next stage skip",
          "[wrong-use][stages]") {
    auto c = smallSheet();
    const int n = c->substepsFor(kDt); // a stage runs once per sub-step
    REQUIRE(n >= 1);
    // A's only owner is the cloth: removing itself used to free it while it ran, and the loop
    // skipped B for that step.
    auto b = std::make_shared<FnStage>("B", nullptr);
    {
        auto a = std::make_shared<FnStage>(
            "A", [](Cloth& cloth) { cloth.removeStage(cloth.stages().front().get()); });
        c->addStage(a);
    }
    c->addStage(b);
    c->step(kDt);
    CHECK(b->runs == n);
    REQUIRE(c->stages().size() == 1);
    CHECK(c->stages().front().get() == b.get());
    c->step(kDt);
    CHECK(b->runs == 2 * n);

    // A stage that removes a later one: that one does not run in the step.
    auto d = std::make_shared<FnStage>("D", nullptr);
    auto e = std::make_shared<FnStage>("E", nullptr);
    auto killer =
        std::make_shared<FnStage>("killer", [&](Cloth& cloth) { cloth.removeStage(d.get()); });
    c->addStage(killer);
    c->addStage(d);
    c->addStage(e);
    c->step(kDt);
    CHECK(b->runs == 3 * n);
    CHECK(d->runs == 0);
    CHECK(e->runs == n);
    CHECK(c->stages().size() == 3);
    CHECK(c->pipeline().size() > 0);
}

namespace {

/// A fresh temporary folder, removed when the test ends.
struct TempDir {
    std::filesystem::path path;
    explicit TempDir(const std::string& name)
        : path(std::filesystem::temp_directory_path() /
               (name + "_" +
                std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()))) {
        std::filesystem::remove_all(path);
        std::filesystem::create_directories(path);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path, ec);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
};

} // namespace

TEST_CASE("A snapshot path that is a folder is refused by name", "[errors][wrong-use][snapshot]") {
    auto c = smallSheet();
    c->step(kDt);
    const std::uint64_t before = stateHash(*c);
    TempDir dir("drape_snapshot_folder");
    // A folder used to let a std::ios_base::failure escape.
    REQUIRE_DRAPE_ERROR(loadSnapshotFile(*c, dir.path.string()), ErrorCode::InvalidArgument,
                        "folder");
    REQUIRE_DRAPE_ERROR(loadSnapshotFile(*c, dir.path.string()), ErrorCode::InvalidArgument,
                        dir.path.string());
    REQUIRE_DRAPE_ERROR(loadSnapshotFile(*c, (dir.path / "missing.snap").string()),
                        ErrorCode::InvalidArgument, "missing.snap");
    REQUIRE_DRAPE_ERROR(loadSnapshotFile(*c, (dir.path / "missing.snap").string()),
                        ErrorCode::InvalidArgument, "cannot open");
    CHECK(stateHash(*c) == before);
    // A real snapshot file still loads.
    const std::string file = (dir.path / "ok.snap").string();
    saveSnapshotFile(*c, file);
    c->step(kDt);
    loadSnapshotFile(*c, file);
    CHECK(stateHash(*c) == before);
}

#if !defined(_WIN32)
TEST_CASE("A snapshot path that is a FIFO is refused by name without blocking",
          "[errors][wrong-use][snapshot]") {
    auto c = smallSheet();
    c->step(kDt);
    const std::uint64_t before = stateHash(*c);
    TempDir dir("drape_snapshot_fifo");
    // A FIFO used to block forever in open(). The load runs on a thread; if it has not
    // returned in 5 s the test opens the FIFO for writing (and closes it) to let it go.
    const std::filesystem::path fifo = dir.path / "snapshot.fifo";
    REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
    std::promise<std::string> result;
    std::future<std::string> done = result.get_future();
    std::thread loader([&] {
        try {
            loadSnapshotFile(*c, fifo.string());
            result.set_value("no error");
        } catch (const Error& e) {
            result.set_value(std::string("drape::Error(") + toString(e.code()) + "): " + e.what());
        } catch (const std::exception& e) {
            result.set_value(std::string("other exception: ") + e.what());
        }
    });
    const bool quick = done.wait_for(std::chrono::seconds(5)) == std::future_status::ready;
    while (done.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready) {
        const int writer = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
        if (writer >= 0) ::close(writer);
    }
    loader.join();
    const std::string message = done.get();
    INFO(message);
    CHECK(quick);
    CHECK_THAT(message, Catch::Matchers::StartsWith("drape::Error(invalid argument)"));
    CHECK_THAT(message, Catch::Matchers::Contains("FIFO"));
    CHECK_THAT(message, Catch::Matchers::Contains(fifo.string()));
    CHECK(stateHash(*c) == before);
}
#endif

TEST_CASE("Enum settings outside their values are refused by name",
          "[errors][wrong-use][settings]") {
    SheetSpec spec;
    spec.rows = 3;
    spec.cols = 3;
    const TopologyPtr topo = ClothTopology::build(makeSheet(spec));
    ClothSettings s;
    s.limiter.kind = static_cast<LimiterKind>(99);
    REQUIRE_DRAPE_ERROR(Cloth(topo, s), ErrorCode::InvalidArgument, "limiter.kind");
    REQUIRE_DRAPE_ERROR(Cloth(topo, s), ErrorCode::InvalidArgument, "StressOrdered");
    s = {};
    s.lumping = static_cast<MassLumping>(99);
    REQUIRE_DRAPE_ERROR(Cloth(topo, s), ErrorCode::InvalidArgument, "lumping");
    s = {};
    s.lumping = static_cast<MassLumping>(-1);
    REQUIRE_DRAPE_ERROR(Cloth(topo, s), ErrorCode::InvalidArgument, "lumping");
    s = {};
    s.integrator = IntegratorKind::ImplicitEuler;
    s.implicit.solver = static_cast<LinearSolverKind>(7);
    REQUIRE_DRAPE_ERROR(Cloth(topo, s), ErrorCode::InvalidArgument, "implicit.solver");
    s = {};
    s.implicit.solver = static_cast<LinearSolverKind>(7); // refused whatever the integrator
    REQUIRE_DRAPE_ERROR(Cloth(topo, s), ErrorCode::InvalidArgument, "implicit.solver");
    s = {};
    s.integrator = static_cast<IntegratorKind>(99);
    REQUIRE_DRAPE_ERROR(Cloth(topo, s), ErrorCode::InvalidArgument, "integrator");
    // Every enumerator is still taken.
    for (auto k : {LimiterKind::None, LimiterKind::StressOrdered, LimiterKind::Provot,
                   LimiterKind::StressOrderedOneSided}) {
        s = {};
        s.limiter.kind = k;
        CHECK_NOTHROW(Cloth(topo, s));
    }
    for (auto l : {MassLumping::Uniform, MassLumping::AreaLumped}) {
        s = {};
        s.lumping = l;
        CHECK_NOTHROW(Cloth(topo, s));
    }
    for (auto solver : {LinearSolverKind::ConjugateGradient, LinearSolverKind::LDLT}) {
        s = {};
        s.integrator = IntegratorKind::ImplicitEuler;
        s.implicit.solver = solver;
        CHECK_NOTHROW(Cloth(topo, s));
    }
}

TEST_CASE("A sleep time of 0 is refused: a falling cloth would fall asleep after one step",
          "[errors][wrong-use][settings][sleep]") {
    ClothSettings s;
    s.sleep.enabled = true;
    s.sleep.time = 0.0;
    SheetSpec spec;
    spec.rows = 3;
    spec.cols = 3;
    const TopologyPtr topo = ClothTopology::build(makeSheet(spec));
    REQUIRE_DRAPE_ERROR(Cloth(topo, s), ErrorCode::InvalidArgument, "sleep.time must be positive");
    auto c = smallSheet();
    SleepSettings sleep;
    sleep.enabled = true;
    sleep.time = 0.0;
    REQUIRE_DRAPE_ERROR(c->setSleep(sleep), ErrorCode::InvalidArgument, "sleep.time");
    c->step(kDt);
    CHECK_FALSE(c->isAsleep()); // falling, and the refused setting left it as it was
    sleep.time = 1e-9;          // tiny but positive: allowed
    c->setSleep(sleep);
}

TEST_CASE("A negative or non-finite minAreaRatio is refused by name", "[errors][wrong-use][mesh]") {
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)}; // collinear: zero area
    m.triangles = {{0, 1, 2}};
    TopologyOptions o;
    o.minAreaRatio = -1.0; // used to let the zero-area triangle through
    REQUIRE_DRAPE_ERROR(ClothTopology::build(m, o), ErrorCode::InvalidArgument,
                        "TopologyOptions::minAreaRatio must be >= 0");
    o.minAreaRatio = std::numeric_limits<double>::quiet_NaN();
    REQUIRE_DRAPE_ERROR(ClothTopology::build(m, o), ErrorCode::InvalidArgument, "minAreaRatio");
    o.minAreaRatio = std::numeric_limits<double>::infinity();
    REQUIRE_DRAPE_ERROR(ClothTopology::build(m, o), ErrorCode::InvalidArgument, "minAreaRatio");
    REQUIRE_DRAPE_ERROR(validateMesh(m, -1.0), ErrorCode::InvalidArgument, "minAreaRatio");
    REQUIRE_DRAPE_ERROR(dropUnusableTriangles(m, -1.0), ErrorCode::InvalidArgument, "minAreaRatio");
    o.minAreaRatio = 0.0; // allowed: the collinear triangle is still degenerate (area 0)
    REQUIRE_DRAPE_ERROR(ClothTopology::build(m, o), ErrorCode::DegenerateTriangle, "triangle 0");
}

TEST_CASE("A NaN the caller wrote before the step is reported as such, not as a blow-up",
          "[errors][wrong-use]") {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (bool velocity : {false, true}) {
        INFO((velocity ? "velocity" : "position"));
        auto c = smallSheet();
        c->step(kDt);
        const Vec3 keep = velocity ? c->velocities()[5] : c->positions()[5];
        const std::uint64_t steps = c->stepCount();
        if (velocity)
            c->mutableVelocities()[5] = Vec3(nan, 0, 0);
        else
            c->mutablePositions()[5] = Vec3(nan, 0, 0);
        try {
            c->step(kDt);
            FAIL("a NaN written before the step was not reported");
        } catch (const Error& e) {
            const std::string what = e.what();
            INFO(what);
            // Used to be: "state became non-finite at particle 3 after the step ... Reduce the
            // time step or the stiffness."
            CHECK(e.code() == ErrorCode::NonFinite);
            CHECK_THAT(what, Catch::Matchers::Contains("particle 5 was not finite before step"));
            CHECK_THAT(what, Catch::Matchers::Contains(velocity ? "mutableVelocities()"
                                                                : "mutablePositions()"));
            CHECK_THAT(what, !Catch::Matchers::Contains("Reduce the time step"));
        }
        CHECK(c->stepCount() == steps);
        // Written back finite, the cloth steps on.
        if (velocity)
            c->mutableVelocities()[5] = keep;
        else
            c->mutablePositions()[5] = keep;
        c->step(kDt);
        CHECK(c->stepCount() == steps + 1);
        for (const Vec3& x : c->positions())
            CHECK(x.allFinite());
    }
}

TEST_CASE("An executor without threads and relimit's bad arguments are refused by name",
          "[errors][wrong-use]") {
    auto c = smallSheet();
    // concurrency() 0 breaks Executor's contract (>= 1, the caller's thread included): one
    // whose parallelFor ran nothing left the cloth's passes unwritten (positions zeroed).
    struct NoThreads : Executor {
        int concurrency() const override { return 0; }
        void parallelFor(std::size_t, std::size_t, const Body&) override {}
    };
    REQUIRE_DRAPE_ERROR(c->setExecutor(std::make_shared<NoThreads>()), ErrorCode::InvalidArgument,
                        "concurrency() is 0");
    c->step(kDt); // still on its own loops
    for (const Vec3& x : c->positions())
        CHECK(x.allFinite());
    // Cloth::relimit (a collision stage's follow-up walk): the step and the particles named.
    const std::vector<Index> touched{0, 1};
    REQUIRE_DRAPE_ERROR(c->relimit(touched, std::numeric_limits<double>::quiet_NaN()),
                        ErrorCode::NonFinite, "time step");
    REQUIRE_DRAPE_ERROR(c->relimit(touched, -kDt), ErrorCode::InvalidArgument, "time step");
    REQUIRE_DRAPE_ERROR(c->relimit({0, 36}, kDt), ErrorCode::IndexOutOfRange,
                        "relimit: particle 36");
    CHECK_NOTHROW(c->relimit(touched, kDt));
}
