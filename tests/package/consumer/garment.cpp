// drape_garment: a garment an artist made, through an installed drape only (tests/package).
// It reads an OBJ skirt with drape::io, hangs its waistband on a kinematic body that walks
// sideways in a Bullet world with every setting left at its default (automatic sub-steps
// included), writes the draped skirt with drape::io, reads it back, and exits non-zero if
// what it sees is not physical.
//
//     drape_garment <skirt.obj> <draped.obj>
#include <drape/bullet/bullet_cloth.hpp>
#include <drape/io/mesh_io.hpp>

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <memory>
#include <vector>

namespace {

int failures = 0;

void expect(bool ok, const char* what, double value) {
    std::printf("%-58s %12.6f  %s\n", what, value, ok ? "ok" : "FAILED");
    if (!ok) ++failures;
}

double meanOf(const std::vector<drape::Vec3>& x, const std::vector<drape::Index>& which, int axis) {
    double sum = 0.0;
    for (drape::Index i : which)
        sum += x[i][axis];
    return sum / static_cast<double>(which.size());
}

int run(const char* garmentFile, const char* outFile) {
    // The artist's garment: welded vertices and the named groups of the OBJ file.
    const drape::io::ImportedMesh garment = drape::io::importMesh(garmentFile);
    auto topology = drape::ClothTopology::build(garment.mesh);
    const auto band = garment.groups.find("waistband");
    if (band == garment.groups.end()) {
        std::printf("drape_garment: %s has no group \"waistband\"\n", garmentFile);
        return 1;
    }
    std::vector<drape::Index> waist; // particles of the waistband's top ring
    double top = -1e9;
    for (const drape::Vec3& v : topology->restPositions())
        top = std::max(top, v.y());
    for (drape::Index v : band->second) {
        const drape::Index p = topology->vertexToParticle()[v];
        if (p != drape::kNoParticle && topology->restPositions()[p].y() > top - 1e-6)
            waist.push_back(p);
    }
    std::vector<drape::Index> hem;
    double bottom = 1e9;
    for (const drape::Vec3& v : topology->restPositions())
        bottom = std::min(bottom, v.y());
    for (drape::Index p = 0; p < topology->particleCount(); ++p)
        if (topology->restPositions()[p].y() < bottom + 1e-6) hem.push_back(p);
    std::printf("drape_garment: %s: %zu particles, %zu springs, waist ring %zu, hem %zu\n",
                garmentFile, topology->particleCount(), topology->springCount(), waist.size(),
                hem.size());

    // The game's world: a floor and a kinematic body inside the waist that walks along x.
    btDefaultCollisionConfiguration configuration;
    btCollisionDispatcher dispatcher(&configuration);
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &configuration);
    world.setGravity(btVector3(0.0f, -9.81f, 0.0f));
    btStaticPlaneShape floorShape(btVector3(0.0f, 1.0f, 0.0f), 0.0f);
    btRigidBody floor(btRigidBody::btRigidBodyConstructionInfo(0.0f, nullptr, &floorShape));
    world.addRigidBody(&floor);
    btCylinderShape hipsShape(btVector3(0.12f, 0.2f, 0.12f));
    btTransform hipsAt(btQuaternion::getIdentity(), btVector3(0.0f, 1.05f, 0.0f));
    btDefaultMotionState hipsMotion(hipsAt);
    btRigidBody hips(btRigidBody::btRigidBodyConstructionInfo(0.0f, &hipsMotion, &hipsShape));
    hips.setCollisionFlags(hips.getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
    hips.setActivationState(DISABLE_DEACTIVATION);
    world.addRigidBody(&hips);

    // Every cloth and world setting at its default.
    auto cloth = std::make_shared<drape::Cloth>(topology, drape::ClothSettings{});
    auto handle = drape::bullet::addCloth(&world, cloth);
    for (drape::Index p : waist)
        handle->attachHere(p, &hips);

    const double speed = 0.3; // m/s along x
    const double waistX0 = meanOf(cloth->positions(), waist, 0);
    const double hemY0 = meanOf(cloth->positions(), hem, 1);
    const int frames = 90;
    double peakStrain = 0.0;
    int substeps = 0;
    for (int frame = 1; frame <= frames; ++frame) {
        hipsAt.setOrigin(btVector3(static_cast<btScalar>(speed * frame / 60.0), 1.05f, 0.0f));
        hipsMotion.setWorldTransform(hipsAt);
        world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
        for (const drape::Vec3& x : cloth->positions())
            if (!x.allFinite()) {
                std::printf("frame %d: non-finite positions\n", frame);
                return 1;
            }
        peakStrain = std::max(peakStrain, cloth->maxStrain());
        substeps = std::max(substeps, handle->lastStats().substeps);
    }
    const std::vector<drape::Vec3>& x = cloth->positions();
    const double walked = speed * frames / 60.0;
    expect(substeps > 1, "automatic cloth sub-steps per 60 Hz step (> 1)",
           static_cast<double>(substeps));
    expect(std::abs(meanOf(x, waist, 0) - waistX0 - walked) < 0.01,
           "waist followed the body: x moved [m] (0.45 +- 0.01)", meanOf(x, waist, 0) - waistX0);
    const double hemDrop = hemY0 - meanOf(x, hem, 1);
    expect(hemDrop > 0.0 && hemDrop < 0.1 * 0.5 + 0.02,
           "hem sank under its weight [m] (0 .. 10 % of 0.5 m + 2 cm)", hemDrop);
    expect(peakStrain <= 0.101, "peak strain over the run (<= 0.101)", peakStrain);

    // The draped garment back to a file, vertex i = particle i, and read again.
    drape::TriangleMesh draped;
    draped.vertices = x;
    draped.triangles = topology->triangles();
    drape::io::exportMesh(draped, outFile);
    const drape::io::ImportedMesh back = drape::io::importMesh(outFile);
    double worst = back.mesh.vertices.size() == x.size() ? 0.0 : 1e9;
    for (std::size_t i = 0; worst < 1e9 && i < x.size(); ++i)
        worst = std::max(worst, (back.mesh.vertices[i] - x[i]).norm());
    expect(worst < 1e-5, "written and read back: largest vertex difference [m]", worst);
    drape::bullet::removeCloth(*handle);

    if (failures > 0) {
        std::printf("drape_garment: %d check(s) failed\n", failures);
        return 1;
    }
    std::printf("drape_garment: all checks passed; wrote %s\n", outFile);
    return 0;
}

} // namespace

int main(int argc, char** argv) {
    if (argc != 3) {
        std::printf("usage: drape_garment <garment.obj> <draped.obj>\n");
        return 2;
    }
    try {
        return run(argv[1], argv[2]);
    } catch (const std::exception& e) {
        std::printf("drape_garment: error: %s\n", e.what());
        return 1;
    }
}
