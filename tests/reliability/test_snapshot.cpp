// Determinism and snapshot/restore of the cloth core.
#include "drape/cloth.hpp"
#include "drape/error.hpp"
#include "drape/snapshot.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

using namespace drape;

namespace {

// A small hanging sheet that exercises every integrator, the limiter, damping and wind.
std::unique_ptr<Cloth> makeCloth(IntegratorKind integrator, LimiterKind limiter,
                                 double damping = 0.001) {
    SheetSpec spec;
    spec.rows = 8;
    spec.cols = 8;
    spec.spacing = 0.1;
    static const TopologyPtr topo = ClothTopology::build(makeSheet(spec));
    ClothSettings s;
    s.integrator = integrator;
    s.particleMass = 0.01;
    s.springStiffness = 50.0;
    s.damping = damping;
    s.limiter.kind = limiter;
    s.aero.airDensity = 1.2;
    s.aero.wind = Vec3(0.0, 0.0, 2.0);
    auto c = std::make_unique<Cloth>(topo, s);
    c->pin(sheetIndex(spec, 0, 0));
    c->pin(sheetIndex(spec, 0, spec.cols - 1));
    return c;
}

/// The bytes with their FNV-1a checksum (the last 8) computed again: a crafted snapshot
/// that passes the checksum, so that what is refused is refused for its content.
std::vector<unsigned char> reseal(std::vector<unsigned char> b) {
    std::uint64_t h = 1469598103934665603ull;
    for (std::size_t i = 0; i + 8 < b.size(); ++i) {
        h ^= b[i];
        h *= 1099511628211ull;
    }
    std::memcpy(b.data() + b.size() - 8, &h, 8);
    return b;
}

} // namespace

TEST_CASE("the same cloth stepped twice gives bit-identical states", "[determinism]") {
    for (auto integrator : {IntegratorKind::VelocityVerlet, IntegratorKind::RungeKutta4,
                            IntegratorKind::ImplicitEuler}) {
        auto a = makeCloth(integrator, LimiterKind::StressOrdered);
        auto b = makeCloth(integrator, LimiterKind::StressOrdered);
        for (int i = 0; i < 200; ++i) {
            a->step(0.002);
            b->step(0.002);
        }
        INFO(toString(integrator));
        CHECK(stateHash(*a) == stateHash(*b));
        // The hash must see the state: one more step changes it.
        const auto before = stateHash(*a);
        a->step(0.002);
        CHECK(stateHash(*a) != before);
    }
}

TEST_CASE("a snapshot carries the aerodynamics Velocity-Verlet takes into its next step",
          "[snapshot][aero]") {
    // Without damping flows the opening kick takes the last closing kick's aerodynamics
    // (ClothState::aero): the snapshot must hold them for the run to continue bit for bit.
    for (auto limiter : {LimiterKind::None, LimiterKind::StressOrdered}) {
        INFO(toString(limiter));
        auto full = makeCloth(IntegratorKind::VelocityVerlet, limiter, 0.0);
        auto resumed = makeCloth(IntegratorKind::VelocityVerlet, limiter, 0.0);
        full->setRelativeDamping(0.0);
        resumed->setRelativeDamping(0.0);
        std::vector<unsigned char> snap;
        for (int i = 0; i < 150; ++i) {
            full->step(0.002);
            if (i == 59) {
                REQUIRE(full->state().aero.size() == full->particleCount());
                snap = saveSnapshot(*full);
            }
        }
        loadSnapshot(*resumed, snap);
        CHECK(resumed->state().aero.size() == resumed->particleCount());
        for (int i = 60; i < 150; ++i)
            resumed->step(0.002);
        CHECK(stateHash(*resumed) == stateHash(*full));
        // An edit of the state drops what was carried: the next step evaluates afresh.
        resumed->setVelocity(5, resumed->velocities()[5]);
        resumed->step(0.002);
        full->step(0.002);
        CHECK(stateHash(*resumed) != stateHash(*full));
    }
}

TEST_CASE("a run restored from a snapshot at step k continues bit-identically", "[snapshot]") {
    for (auto integrator : {IntegratorKind::VelocityVerlet, IntegratorKind::ExplicitEuler,
                            IntegratorKind::SymplecticEuler, IntegratorKind::RungeKutta4,
                            IntegratorKind::ImplicitEuler}) {
        for (auto limiter : {LimiterKind::None, LimiterKind::StressOrdered, LimiterKind::Provot}) {
            INFO(toString(integrator) << " / " << toString(limiter));
            auto full = makeCloth(integrator, limiter);
            auto resumed = makeCloth(integrator, limiter);
            std::vector<unsigned char> snap;
            for (int i = 0; i < 150; ++i) {
                full->step(0.002);
                if (i == 59) snap = saveSnapshot(*full);
            }
            loadSnapshot(*resumed, snap);
            CHECK(resumed->stepCount() == 60);
            for (int i = 60; i < 150; ++i)
                resumed->step(0.002);
            CHECK(stateHash(*resumed) == stateHash(*full));
            CHECK(resumed->time() == full->time());
        }
    }
}

TEST_CASE("a snapshot taken while the cloth is held beyond its bound continues bit-identically",
          "[snapshot][limiter]") {
    // The sheet of makeCloth with its two pins moved 1.5 times the sheet's width apart: the
    // limiter stops at its cap in every step (ClothState::overBound), which the next step's
    // repair walk reads. The snapshot carries the flag; taken there and restored, the run
    // continues with the same bits, and one of the pins let go is repaired the same way.
    auto full = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    auto resumed = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    full->pin(7, full->positions()[7] + Vec3(0.75, 0.0, 0.0));
    std::vector<unsigned char> snap;
    for (int i = 0; i < 40; ++i) {
        if (i == 30) full->unpin(7);
        full->step(0.01);
        if (i == 19) {
            REQUIRE(full->state().overBound);
            snap = saveSnapshot(*full);
        }
    }
    loadSnapshot(*resumed, snap);
    CHECK(resumed->state().overBound);
    for (int i = 20; i < 40; ++i) {
        if (i == 30) resumed->unpin(7);
        resumed->step(0.01);
    }
    CHECK(stateHash(*resumed) == stateHash(*full));
    CHECK(!resumed->state().overBound); // let go and repaired
    // The flag matters: the same state with it cleared continues differently.
    auto cleared = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    loadSnapshot(*cleared, snap);
    ClothState st = cleared->state();
    st.overBound = false;
    cleared->restoreState(st, cleared->limiter().warmStartState());
    for (int i = 20; i < 40; ++i) {
        if (i == 30) cleared->unpin(7);
        cleared->step(0.01);
    }
    CHECK(stateHash(*cleared) != stateHash(*full));
}

TEST_CASE("a state read with Cloth::state() and put back with restoreState continues "
          "bit-identically, and a state of the wrong size is refused",
          "[snapshot]") {
    auto full = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    auto resumed = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    ClothState kept;
    std::vector<double> warm;
    for (int i = 0; i < 150; ++i) {
        full->step(0.002);
        if (i == 59) {
            kept = full->state();
            warm = full->limiter().warmStartState();
        }
    }
    // Wrong sizes: named, and the cloth is left as it was.
    const auto before = stateHash(*resumed);
    ClothState shorter = kept;
    shorter.v.pop_back();
    CHECK_THROWS_WITH(resumed->restoreState(shorter, warm), Catch::Contains("v has"));
    CHECK_THROWS_WITH(resumed->restoreState(kept, std::vector<double>(3, 0.0)),
                      Catch::Contains("warmStart"));
    ClothState broken = kept;
    broken.x[5].y() = std::nan("");
    CHECK_THROWS_WITH(resumed->restoreState(broken, warm), Catch::Contains("x of particle 5"));
    CHECK(stateHash(*resumed) == before);
    resumed->restoreState(kept, warm);
    CHECK(resumed->stepCount() == 60);
    for (int i = 60; i < 150; ++i)
        resumed->step(0.002);
    CHECK(stateHash(*resumed) == stateHash(*full));
    // Without the warm start the limiter starts afresh: the run is a different one.
    auto cold = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    cold->restoreState(kept, {});
    for (int i = 60; i < 150; ++i)
        cold->step(0.002);
    CHECK(stateHash(*cold) != stateHash(*full));
}

TEST_CASE("snapshot files round-trip and corrupt or truncated ones are refused", "[snapshot]") {
    auto cloth = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    for (int i = 0; i < 20; ++i)
        cloth->step(0.002);
    const std::string path = "drape_test_snapshot.bin";
    saveSnapshotFile(*cloth, path);
    auto other = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    loadSnapshotFile(*other, path);
    CHECK(stateHash(*other) == stateHash(*cloth));
    std::remove(path.c_str());

    const auto good = saveSnapshot(*cloth);
    auto fresh = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    const auto freshHash = stateHash(*fresh);

    auto truncated = good;
    truncated.resize(good.size() / 2);
    CHECK_THROWS_WITH(loadSnapshot(*fresh, truncated), Catch::Contains("truncated"));

    auto flipped = good;
    flipped[good.size() / 2] ^= 0x40;
    CHECK_THROWS_WITH(loadSnapshot(*fresh, flipped), Catch::Contains("corrupt"));

    auto notASnapshot = good;
    notASnapshot[0] = 'X';
    CHECK_THROWS_WITH(loadSnapshot(*fresh, notASnapshot), Catch::Contains("not a drape snapshot"));
    CHECK_THROWS_WITH(loadSnapshotFile(*fresh, "no/such/file.bin"), Catch::Contains("cannot open"));

    // A snapshot of a different cloth is refused.
    SheetSpec spec;
    spec.rows = 3;
    spec.cols = 3;
    ClothSettings s;
    s.particleMass = 1.0;
    s.springStiffness = 1.0;
    Cloth small(ClothTopology::build(makeSheet(spec)), s);
    CHECK_THROWS_WITH(loadSnapshot(small, good), Catch::Contains("particles"));

    // Refused loads leave the cloth untouched.
    CHECK(stateHash(*fresh) == freshHash);
}

TEST_CASE("a step that blows up throws and leaves the last good state", "[blowup]") {
    SheetSpec spec;
    spec.rows = 4;
    spec.cols = 4;
    spec.spacing = 0.1;
    ClothSettings s;
    s.integrator = IntegratorKind::ExplicitEuler;
    s.particleMass = 0.01;
    s.springStiffness = 1e4;
    s.limiter.kind = LimiterKind::None;
    s.rejectUnstableTimeStep = false; // let it explode on purpose
    s.substeps.automatic = false;     // each step is the dt given
    Cloth cloth(ClothTopology::build(makeSheet(spec)), s);
    cloth.setVelocity(5, Vec3(0.0, 0.0, 1.0));
    const double dt = 20.0 * cloth.stableTimeStep();
    bool threw = false;
    for (int i = 0; i < 2000 && !threw; ++i) {
        const auto before = stateHash(cloth);
        const auto steps = cloth.stepCount();
        try {
            cloth.step(dt);
        } catch (const Error& e) {
            threw = true;
            CHECK(e.code() == ErrorCode::SimulationFailure);
            CHECK(stateHash(cloth) == before);
            CHECK(cloth.stepCount() == steps);
        }
    }
    CHECK(threw);
    for (const auto& x : cloth.positions())
        CHECK(x.allFinite());
}

namespace {
/// A square sheet of n x n particles.
SheetSpec squareSheet(Index n, double spacing) {
    SheetSpec spec;
    spec.rows = n;
    spec.cols = n;
    spec.spacing = spacing;
    return spec;
}
/// The integrators whose particle loops are split over threads.
constexpr IntegratorKind kSplitIntegrators[] = {
    IntegratorKind::VelocityVerlet, IntegratorKind::SymplecticEuler, IntegratorKind::RungeKutta4};
} // namespace

TEST_CASE("one and two threads give bit-identical states", "[determinism][threads]") {
    // 300 x 300 particles: above the size where the pool splits loops (32768 per thread), so
    // the second thread's range starts inside the sheet.
    const SheetSpec spec = squareSheet(300, 0.01);
    const TopologyPtr topo = ClothTopology::build(makeSheet(spec));
    for (auto integrator : kSplitIntegrators) {
        std::uint64_t hashes[2] = {0, 0};
        for (int threads = 1; threads <= 2; ++threads) {
            ClothSettings s;
            s.integrator = integrator;
            s.threads = threads;
            s.particleMass = 1e-4;
            s.springStiffness = 10.0;
            s.damping = 1e-5;
            Cloth cloth(topo, s);
            cloth.pin(sheetIndex(spec, 0, 0));
            cloth.pin(sheetIndex(spec, 0, spec.cols - 1));
            for (int i = 0; i < 20; ++i)
                cloth.step(1e-3);
            hashes[threads - 1] = stateHash(cloth);
        }
        INFO(toString(integrator));
        CHECK(hashes[0] == hashes[1]);
    }
}

namespace {
/// An executor that splits every loop into pieces of at most 97 elements (at least two pieces
/// for any loop of two or more) whatever its grain, runs them last piece first, and the odd ones
/// on a second thread: any split and order must give the same bits (drape/executor.hpp).
class ScatteringExecutor final : public Executor {
  public:
    int concurrency() const override { return 2; }
    void parallelFor(std::size_t n, std::size_t, const Body& body) override {
        ++loops;
        const std::size_t piece = std::max<std::size_t>(1, std::min<std::size_t>(97, n / 2));
        const std::size_t pieces = (n + piece - 1) / piece;
        auto run = [&](std::size_t k) { body(piece * k, std::min(n, piece * (k + 1))); };
        std::thread other([&] {
            for (std::size_t k = pieces; k-- > 0;)
                if (k % 2 == 1) run(k);
        });
        for (std::size_t k = pieces; k-- > 0;)
            if (k % 2 == 0) run(k);
        other.join();
    }
    std::size_t loops = 0;
};
} // namespace

TEST_CASE("a caller's executor runs the step's loops with the same bits as one thread",
          "[determinism][threads]") {
    // 130 x 130: more than 16384 particles, so the spring and damping passes have two blocks
    // and the limiter's scan two segments (each loop is split).
    const SheetSpec spec = squareSheet(130, 0.01);
    const TopologyPtr topo = ClothTopology::build(makeSheet(spec));
    for (auto integrator : kSplitIntegrators) {
        INFO(toString(integrator));
        ClothSettings s;
        s.integrator = integrator;
        s.springDamping = 0.01; // the damping sweep's blocks go through the executor too
        auto run = [&](const std::shared_ptr<ScatteringExecutor>& executor) {
            Cloth cloth(topo, s);
            cloth.pin(sheetIndex(spec, 0, 0));
            cloth.pin(sheetIndex(spec, 0, spec.cols - 1));
            cloth.setExecutor(executor);
            CHECK(cloth.hasCallerExecutor() == (executor != nullptr));
            CHECK(cloth.executor() == executor.get());
            for (int i = 0; i < 20; ++i)
                cloth.step(1e-3);
            return stateHash(cloth);
        };
        const std::uint64_t alone = run(nullptr);
        auto executor = std::make_shared<ScatteringExecutor>();
        const std::uint64_t scattered = run(executor);
        CHECK(executor->loops > 20); // it ran the loops (several a step)
        CHECK(scattered == alone);
    }
    // Null gives the loops back to the cloth's own pool (threads > 1) or to this thread.
    ClothSettings two;
    two.threads = 2;
    Cloth cloth(topo, two);
    CHECK(cloth.executor() == nullptr); // the pool starts with the first step that needs it
    cloth.step(1e-3);
    const Executor* own = cloth.executor();
    REQUIRE(own != nullptr);
    cloth.setExecutor(std::make_shared<ScatteringExecutor>());
    CHECK(cloth.executor() != own);
    cloth.setExecutor(nullptr);
    CHECK(cloth.executor() == own);
    CHECK_FALSE(cloth.hasCallerExecutor());
}

namespace {
/// A caller stage with state of its own: it counts its runs and nudges one particle by it.
class CountingStage final : public ClothStage {
  public:
    std::string name() const override { return "counting"; }
    void run(Cloth& c, double) override {
        ++runs;
        c.mutablePositions()[5].x() += 1e-6 * double(runs % 7);
    }
    std::vector<unsigned char> saveState() const override {
        std::vector<unsigned char> b(sizeof runs);
        std::memcpy(b.data(), &runs, sizeof runs);
        return b;
    }
    void loadState(const std::vector<unsigned char>& b) override {
        if (b.empty()) {
            runs = 0;
            return;
        }
        if (b.size() != sizeof runs) throw Error(ErrorCode::InvalidArgument, "bad counter");
        std::memcpy(&runs, b.data(), sizeof runs);
    }
    std::uint64_t runs = 0;
};
} // namespace

TEST_CASE("snapshots carry the caller stages' states, matched by name", "[snapshot]") {
    auto full = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    auto stage = std::make_shared<CountingStage>();
    full->addStage(stage);
    for (int i = 0; i < 40; ++i)
        full->step(0.002);
    const auto snap = saveSnapshot(*full);
    for (int i = 0; i < 40; ++i)
        full->step(0.002);

    // Restored with the stage: its counter comes back and the run repeats bit for bit.
    auto resumed = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    auto again = std::make_shared<CountingStage>();
    resumed->addStage(again);
    loadSnapshot(*resumed, snap);
    CHECK(again->runs == 40);
    for (int i = 0; i < 40; ++i)
        resumed->step(0.002);
    CHECK(stateHash(*resumed) == stateHash(*full));

    // A bare cloth ignores the stage's state; a stage the snapshot does not name starts afresh.
    auto bare = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    CHECK_NOTHROW(loadSnapshot(*bare, snap));
    auto plain = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    const auto noStages = saveSnapshot(*plain);
    loadSnapshot(*resumed, noStages);
    CHECK(again->runs == 0);
}

TEST_CASE("a crafted snapshot with a valid checksum but impossible lengths is refused",
          "[snapshot][errors]") {
    // Lengths inside the file are checked against what is left of it before anything is read
    // or allocated: a stage state claiming 2^60 bytes, or 2^31 stages, is refused by name.
    auto cloth = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    cloth->addStage(std::make_shared<CountingStage>());
    cloth->step(0.002);
    const auto good = saveSnapshot(*cloth);
    // Layout of the tail: ... u32 stage count, u32 name length, "counting", u64 state length,
    // 8 state bytes, u64 checksum.
    const std::size_t stateLength = good.size() - 8 - 8 - 8;
    const std::size_t stageCount = stateLength - 8 - 4 - 4;
    auto huge = good;
    const std::uint64_t big = std::uint64_t(1) << 60;
    std::memcpy(huge.data() + stateLength, &big, 8);
    auto fresh = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    fresh->addStage(std::make_shared<CountingStage>());
    CHECK_THROWS_WITH(loadSnapshot(*fresh, reseal(huge)), Catch::Contains("truncated"));
    auto many = good;
    const std::uint32_t count = 0x80000000u;
    std::memcpy(many.data() + stageCount, &count, 4);
    CHECK_THROWS_WITH(loadSnapshot(*fresh, reseal(many)), Catch::Contains("stages"));
    // A NaN position with a valid checksum: refused by name before the stages take their
    // states (Cloth::checkState), so the stage keeps its count.
    auto nan = good;
    const double x0 = cloth->positions()[0].x();
    const auto at = std::search(nan.begin(), nan.end(), reinterpret_cast<const unsigned char*>(&x0),
                                reinterpret_cast<const unsigned char*>(&x0) + 8);
    REQUIRE(at != nan.end());
    const double bad = std::nan("");
    std::memcpy(&*at, &bad, 8);
    auto stage = std::make_shared<CountingStage>();
    stage->runs = 7;
    auto target = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    target->addStage(stage);
    CHECK_THROWS_WITH(loadSnapshot(*target, reseal(nan)), Catch::Contains("x of particle 0"));
    CHECK(stage->runs == 7);
    // The untouched file still loads (the offsets above are the real ones).
    CHECK_NOTHROW(loadSnapshot(*fresh, reseal(good)));
}

TEST_CASE("a version 3 snapshot still loads (its next step evaluates the aerodynamics), and "
          "non-finite carried aerodynamics are refused",
          "[snapshot][errors][aero]") {
    auto cloth = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered, 0.0);
    cloth->setRelativeDamping(0.0);
    for (int i = 0; i < 20; ++i)
        cloth->step(0.002);
    const std::size_t n = cloth->particleCount(), ns = cloth->topology().springCount();
    REQUIRE(cloth->state().aero.size() == n);
    const std::size_t anchors = cloth->state().anchor.size() == n ? n * 3 * 8 : 0;
    const auto good = saveSnapshot(*cloth);
    // Layout (snapshot.hpp): magic 8, version 4, fingerprint 8, count 8, time 8, steps 8,
    // forces flag 1, per particle 9 f64 and a pin byte, per spring a f64, asleep 1, quiet time
    // 8, anchor flag 1 and the anchors, then version 4's aerodynamics flag and forces, then
    // version 5's over-bound flag, then version 6's strain bound (f64).
    const std::size_t flag =
        8 + 4 + 8 + 8 + 8 + 8 + 1 + n * (9 * 8 + 1) + ns * 8 + 1 + 8 + 1 + anchors;
    REQUIRE(good[flag] == 1);
    // Version 3: the same without the aerodynamics, the over-bound flag and the bound.
    REQUIRE(good[flag + 1 + n * 3 * 8] == 0); // not over the bound
    double bound = 0.0;
    std::memcpy(&bound, good.data() + flag + 1 + n * 3 * 8 + 1, 8);
    REQUIRE(bound == cloth->settings().limiter.maxStrain);
    std::vector<unsigned char> old(good.begin(), good.begin() + std::ptrdiff_t(flag));
    old.insert(old.end(), good.begin() + std::ptrdiff_t(flag + 1 + n * 3 * 8 + 1 + 8), good.end());
    const std::uint32_t three = 3;
    std::memcpy(old.data() + 8, &three, 4);
    auto resumed = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered, 0.0);
    resumed->setRelativeDamping(0.0);
    REQUIRE_NOTHROW(loadSnapshot(*resumed, reseal(old)));
    CHECK(resumed->state().aero.empty());
    CHECK(stateHash(*resumed) == stateHash(*cloth));
    const PhaseTimer* before = resumed->timers().find("aero");
    const std::uint64_t calls = before ? before->calls : 0;
    resumed->step(0.002);
    CHECK(resumed->timers().find("aero")->calls == calls + 2); // both kicks evaluated
    // A NaN among the carried forces: refused by name.
    auto bad = good;
    const double nan = std::nan("");
    std::memcpy(bad.data() + flag + 1, &nan, 8);
    auto target = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered, 0.0);
    CHECK_THROWS_WITH(loadSnapshot(*target, reseal(bad)), Catch::Contains("aero"));
}

TEST_CASE("a state restored into a cloth with a tighter bound is brought within it as "
          "positions, not thrown",
          "[snapshot][limiter]") {
    // Review 20: an editor tightened the bound of a hanging curtain (soft springs: the limiter
    // holds it at 0.1) by building a cloth with maxStrain 0.02 and restoring the state into
    // it; the walk's corrections became speed: 25 m/s.
    SheetSpec spec;
    spec.rows = 21;
    spec.cols = 21;
    spec.spacing = 0.05;
    const TopologyPtr topo = ClothTopology::build(makeSheet(spec));
    ClothSettings s;
    s.springStiffness = 3.0;
    Cloth loose(topo, s);
    for (Index j = 0; j < spec.cols; ++j)
        loose.pin(j);
    for (int f = 0; f < 240; ++f)
        loose.step(1.0 / 60.0);
    REQUIRE(loose.maxStrain() > 0.09);
    REQUIRE_FALSE(loose.state().overBound);
    CHECK(loose.state().bound == s.limiter.maxStrain);
    const auto bytes = saveSnapshot(loose);
    for (const bool fromBytes : {false, true}) {
        ClothSettings tight = s;
        tight.limiter.maxStrain = 0.02;
        Cloth c(topo, tight);
        if (fromBytes)
            loadSnapshot(c, bytes);
        else
            c.restoreState(loose.state(), loose.limiter().warmStartState());
        INFO((fromBytes ? "loadSnapshot" : "restoreState"));
        CHECK(c.state().overBound);
        CHECK(c.state().bound == tight.limiter.maxStrain);
        double fastest = 0.0;
        for (int f = 0; f < 60; ++f) {
            c.step(1.0 / 60.0);
            for (const Vec3& v : c.velocities())
                fastest = std::max(fastest, v.norm());
        }
        CHECK(fastest < 1.0);
        CHECK(c.maxStrain() <= tight.limiter.maxStrain + tight.limiter.tolerance);
    }
    // The same bound: nothing to bring back, the run continues as it was.
    Cloth same(topo, s);
    same.restoreState(loose.state(), loose.limiter().warmStartState());
    CHECK_FALSE(same.state().overBound);
    loose.step(1.0 / 60.0);
    same.step(1.0 / 60.0);
    CHECK(stateHash(same) == stateHash(loose));
}

TEST_CASE("a restored snapshot drops the kinematic path of a particle it frees", "[snapshot]") {
    // Review 20: a drag in progress (setKinematicTarget) when an editor loaded its snapshot
    // went on moving a particle that the snapshot freed and isPinned() called free.
    auto a = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    for (int i = 0; i < 20; ++i)
        a->step(0.002);
    const auto bytes = saveSnapshot(*a);
    const Index dragged = 60;
    a->setKinematicTarget(dragged, a->positions()[dragged] + Vec3(0.0, 0.0, 0.5), a->time() + 0.5);
    a->step(0.002);
    loadSnapshot(*a, bytes);
    CHECK_FALSE(a->isPinned(dragged));
    auto b = makeCloth(IntegratorKind::VelocityVerlet, LimiterKind::StressOrdered);
    loadSnapshot(*b, bytes);
    for (int i = 0; i < 50; ++i) {
        a->step(0.002);
        b->step(0.002);
    }
    CHECK(stateHash(*a) == stateHash(*b));
}
