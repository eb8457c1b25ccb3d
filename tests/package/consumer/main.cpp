// drape_consumer: the README's "Putting a cloth into a Bullet world", as a program built
// against an installed drape (find_package(drape CONFIG REQUIRED), tests/package). It hangs
// the README's curtain from a pole, lets a second sheet fall freely beside it, and exits
// non-zero if what it sees is not physical. The falling sheet runs its loops on the program's
// own threads (drape::Executor, Cloth::setExecutor).
#include <drape/bullet/bullet_cloth.hpp>
#include <drape/executor.hpp>

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

namespace {

int failures = 0;

void expect(bool ok, const char* what, double value) {
    std::printf("%-58s %12.6f  %s\n", what, value, ok ? "ok" : "FAILED");
    if (!ok) ++failures;
}

double meanHeight(const std::vector<drape::Vec3>& x) {
    double sum = 0.0;
    for (const drape::Vec3& p : x)
        sum += p.y();
    return sum / static_cast<double>(x.size());
}

bool allFinite(const std::vector<drape::Vec3>& x) {
    for (const drape::Vec3& p : x) {
        if (!p.allFinite()) return false;
    }
    return true;
}

/// The program's threads as an executor: the second half of every loop on another thread.
class TwoThreads final : public drape::Executor {
  public:
    int concurrency() const override { return 2; }
    void parallelFor(std::size_t n, std::size_t, const Body& body) override {
        ++loops;
        std::thread other([&] { body(n / 2, n); });
        body(0, n / 2);
        other.join();
    }
    std::size_t loops = 0;
};

} // namespace

int main() {
    // The application's Bullet world.
    btDefaultCollisionConfiguration configuration;
    btCollisionDispatcher dispatcher(&configuration);
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld dynamicsWorld(&dispatcher, &broadphase, &solver, &configuration);
    dynamicsWorld.setGravity(btVector3(0.0f, -9.81f, 0.0f));
    btDiscreteDynamicsWorld* world = &dynamicsWorld;

    // The pole: a kinematic capsule along x at the curtain's top edge.
    btCapsuleShapeX poleShape(0.02f, 1.0f);
    btDefaultMotionState poleMotion(
        btTransform(btQuaternion::getIdentity(), btVector3(0.0f, 1.5f, 0.0f)));
    btRigidBody poleBody(btRigidBody::btRigidBodyConstructionInfo(0.0f, &poleMotion, &poleShape));
    poleBody.setCollisionFlags(poleBody.getCollisionFlags() |
                               btCollisionObject::CF_KINEMATIC_OBJECT);
    poleBody.setActivationState(DISABLE_DEACTIVATION);
    world->addRigidBody(&poleBody);
    btRigidBody* pole = &poleBody;

    // --- README: "Putting a cloth into a Bullet world" ------------------------------------
    // clang-format off
    drape::SheetSpec sheet;              // a 1 m x 1 m curtain in the x-y plane
    sheet.rows = 21;
    sheet.cols = 21;
    sheet.spacing = 0.05;                // m
    sheet.origin = {-0.5, 1.5, 0.0};     // top-left corner, m
    drape::ClothSettings settings;       // Velocity-Verlet, stress-ordered 10 % strain limit
    settings.totalMass = 0.3;            // kg
    settings.springStiffness = 20.0;     // N/m (or settings.material: E, thickness, density)
    auto cloth = std::make_shared<drape::Cloth>(
        drape::ClothTopology::build(drape::makeSheet(sheet)), settings);

    drape::bullet::BulletClothSettings options;
    options.contact.thickness = 0.005;   // m
    options.substeps = 2;                // cloth steps per Bullet sub-step
    auto handle = drape::bullet::addCloth(world, cloth, options);              // one call in
    for (drape::Index c = 0; c < sheet.cols; ++c) handle->attachHere(c, pole); // hang it
    // clang-format on
    // ---------------------------------------------------------------------------------------

    // A second sheet, attached to nothing, 3 m to the side: it falls freely.
    drape::SheetSpec freeSheet = sheet;
    freeSheet.rows = 5;
    freeSheet.cols = 5;
    freeSheet.origin = {3.0, 1.5, 0.0};
    auto falling = std::make_shared<drape::Cloth>(
        drape::ClothTopology::build(drape::makeSheet(freeSheet)), settings);
    auto threads = std::make_shared<TwoThreads>();
    falling->setExecutor(threads);
    auto fallingHandle = drape::bullet::addCloth(world, falling, options);

    const double curtainStart = meanHeight(cloth->positions());
    const double fallingStart = meanHeight(falling->positions());
    const int frames = 30;
    for (int frame = 0; frame < frames; ++frame) {
        world->stepSimulation(1.0f / 60.0f, 10, 1.0f / 240.0f); // rigid bodies and cloth together
        const std::vector<drape::Vec3>& x = cloth->positions(); // render from here
        if (!allFinite(x) || !allFinite(falling->positions())) {
            std::printf("frame %d: non-finite positions\n", frame);
            return 1;
        }
    }
    drape::bullet::removeCloth(*handle); // one call out
    drape::bullet::removeCloth(*fallingHandle);

    const std::vector<drape::Vec3>& x = cloth->positions();
    const double time = frames / 60.0;
    const double freeFall = 0.5 * 9.81 * time * time;
    std::printf("drape_consumer: %d frames (%.3f s), %llu cloth steps\n", frames, time,
                static_cast<unsigned long long>(cloth->stepCount()));
    expect(cloth->stepCount() == static_cast<std::uint64_t>(frames) * 4 * 2,
           "cloth steps (frames x 4 sub-steps x 2)", static_cast<double>(cloth->stepCount()));
    expect(threads->loops > 0 && falling->executor() == threads.get(),
           "free sheet: loops run on the program's executor", static_cast<double>(threads->loops));
    // The free sheet falls as a body does: 0.5 g t^2 (no drag, no damping).
    const double fallen = fallingStart - meanHeight(falling->positions());
    expect(std::abs(fallen - freeFall) < 0.02 * freeFall, "free sheet: drop [m] (0.5 g t^2 +- 2 %)",
           fallen);
    // The curtain stays on its pole and sags under its weight, at most by its 10 % strain limit.
    double topError = 0.0;
    for (drape::Index c = 0; c < sheet.cols; ++c) {
        topError = std::max(topError, std::abs(x[c].y() - 1.5));
    }
    expect(topError < 1e-3, "curtain: top row off the pole [m]", topError);
    const double sag = curtainStart - meanHeight(x);
    expect(sag > 1e-3, "curtain: mean height fell [m]", sag);
    const double bottom = x[drape::sheetIndex(sheet, sheet.rows - 1, sheet.cols / 2)].y();
    expect(bottom < 0.5 && bottom > 1.5 - 1.0 * 1.1 - 0.01,
           "curtain: bottom centre height [m] (0.39 .. 0.5)", bottom);
    if (failures > 0) {
        std::printf("drape_consumer: %d check(s) failed\n", failures);
        return 1;
    }
    std::printf("drape_consumer: all checks passed\n");
    return 0;
}
