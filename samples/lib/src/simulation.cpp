// simulation.cpp: builds a cloth (and its rigid world) from a scene and steps it.
#include "drape_samples/simulation.hpp"

#include "drape_samples/check.hpp"
#include "drape_samples/mesh_io.hpp"
#include "rigid_world.hpp"

#include <drape/error.hpp>
#include <drape/stability.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>

namespace drape::samples {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string num(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", x);
    return buf;
}

std::string origin(const SceneDesc& s) {
    return s.sourceFile.empty() ? std::string("scene") : s.sourceFile.string();
}

/// Mesh files already imported for drawing, by path: a file that many bodies name is read
/// once.
using ImportedMeshes = std::map<std::string, ImportedMesh>;

std::vector<DrawMesh> shapeMeshes(const RigidBodyDesc& b, const Vec3& around, double planeSize,
                                  std::vector<std::string>& warnings, ImportedMeshes& imported) {
    DrawMesh m;
    switch (b.shape.kind) {
    case ShapeKind::Box:
        m = makeBoxMesh(b.shape.halfExtents);
        break;
    case ShapeKind::Sphere:
        m = makeSphereMesh(b.shape.radius);
        break;
    case ShapeKind::Capsule:
        m = makeCapsuleMesh(b.shape.radius, b.shape.height);
        break;
    case ShapeKind::Plane:
        // Planes are infinite and static: draw a checkered square under the cloth, in world space.
        return makePlaneMeshes(b.shape.normal, b.shape.offset, around, planeSize, b.color);
    case ShapeKind::Mesh: {
        const std::string key = meshDescKey(b.shape.mesh);
        auto it = imported.find(key);
        if (it == imported.end()) {
            it = imported.emplace(key, importMesh(b.shape.mesh, false)).first; // a body
            warnings.insert(warnings.end(), it->second.warnings.begin(), it->second.warnings.end());
        }
        const ImportedMesh& im = it->second;
        m = toDrawMesh(im.mesh.vertices, im.mesh.triangles, b.color, b.color);
        break;
    }
    }
    m.front = m.back = b.color;
    return {m};
}

} // namespace

Simulation::Simulation(const SceneDesc& scene) : scene_(scene) {
    TriangleMesh mesh;
    std::map<std::string, std::vector<Index>> groups;
    if (scene_.sheet) {
        try {
            mesh = makeSheet(scene_.sheet->spec);
        } catch (const drape::Error& e) {
            fail("cloth.sheet", e.what());
        }
    } else {
        ImportedMesh im = importMesh(*scene_.mesh); // SceneError names the file
        warnings_ = std::move(im.warnings);
        mesh = std::move(im.mesh);
        groups = std::move(im.groups);
    }
    if (mesh.vertices.size() > kMaxSceneParticles)
        fail("cloth", std::to_string(mesh.vertices.size()) + " particles exceeds the limit of " +
                          std::to_string(kMaxSceneParticles));

    TopologyPtr topo;
    try {
        TopologyOptions opts;
        if (scene_.mesh) opts.weldTolerance = scene_.mesh->weldTolerance;
        topo = ClothTopology::build(mesh, opts);
    } catch (const drape::Error& e) {
        fail(scene_.mesh ? "cloth.mesh (" + scene_.mesh->file.string() + ")" : "cloth.sheet",
             e.what());
    }
    // "auto" picks the count once, from the stability limits at the start. The aerodynamics'
    // limit falls as the cloth speeds up against the wind: with air the cloth's own automatic
    // sub-steps also split each of those steps as its speed asks (as a program's Cloth::step
    // does). A cloth in water in a 1 m/s current took 80 sub-steps from t = 0, needed 333 by
    // its 20th frame and blew up (review 16). Without air the limit never moves: the same
    // steps as before.
    if (scene_.autoSubsteps && scene_.cloth.aero.airDensity > 0.0)
        scene_.cloth.substeps.automatic = true;
    try {
        cloth_ = std::make_unique<Cloth>(topo, scene_.cloth);
    } catch (const drape::Error& e) {
        fail("cloth", e.what());
    }
    const Vec3 g = scene_.cloth.gravity;
    up_ = g.norm() > 0.0 ? Vec3(-g.normalized()) : Vec3::UnitY();

    const auto& v2p = topo->vertexToParticle();
    const std::size_t entries = scene_.pins.size() + scene_.attachments.size();
    if (entries > kMaxSelectionWork / cloth_->particleCount())
        fail(scene_.pins.empty() ? "attachments" : "pins",
             std::to_string(scene_.pins.size()) + " pins and " +
                 std::to_string(scene_.attachments.size()) + " attachments on " +
                 std::to_string(cloth_->particleCount()) +
                 " particles: each entry looks at every particle, and entries x particles "
                 "exceeds the limit of " +
                 std::to_string(kMaxSelectionWork) +
                 " (select many particles in one entry: a box, a group, a list of indices)");
    for (const PinDesc& pin : scene_.pins) {
        std::vector<Index> set = resolve(pin.select, v2p, groups);
        for (Index i : set) {
            if (pin.velocity.isZero()) {
                cloth_->pin(i);
            } else {
                const Vec3 x0 = cloth_->positions()[i];
                const Vec3 vel = pin.velocity;
                const double t0 = pin.startTime, t1 = pin.endTime;
                cloth_->setKinematic(i, [x0, vel, t0, t1](double t) {
                    return Vec3(x0 + vel * (std::clamp(t, t0, t1) - t0));
                });
            }
        }
        pinSets_.push_back(std::move(set));
    }
    for (const AttachmentDesc& a : scene_.attachments)
        attachSets_.push_back(resolve(a.select, v2p, groups));

    // Rigid bodies: drawables first (a broken collider mesh is reported before Bullet runs).
    Vec3 lo = cloth_->positions()[0], hi = lo;
    for (const Vec3& x : cloth_->positions()) {
        lo = lo.cwiseMin(x);
        hi = hi.cwiseMax(x);
    }
    const Vec3 centre = 0.5 * (lo + hi);
    const double planeSize =
        4.0 * std::max((hi - lo).norm(), (scene_.camera.position - centre).norm());
    ImportedMeshes imported;
    for (const RigidBodyDesc& b : scene_.rigidBodies)
        bodyMeshes_.push_back(shapeMeshes(b, centre, planeSize, warnings_, imported));
    chooseSubsteps();
    warnStiffSpot();
    warnLongRun();
    if (scene_.needsBullet()) world_ = RigidWorld::create(scene_, *cloth_, attachSets_);
    applyWind();
}

Simulation::~Simulation() = default;

void Simulation::chooseSubsteps() {
    if (!scene_.autoSubsteps) return; // scene_.substeps as the file gave it
    // The stability estimate with the pins in place (attachments, added with the world,
    // only remove free particles, which never lowers the limit).
    // The explicit aerodynamics' limit too, at the strongest wind of the gusts (a cloth in
    // water, or in a gale); applyWind sets the wind of the moment after.
    if (scene_.wind) cloth_->setWind(scene_.wind->strongest());
    const double dt = scene_.timeStep;
    // Explicit Euler's own limit (the cloth's stableTimeStep is Velocity-Verlet's for it): it
    // is stable only as far as damping reaches (review 17: "auto" took Velocity-Verlet's count
    // for it, and the cloth blew up).
    const double springs = springsTimeStep(*cloth_, scene_.cloth.integrator);
    if (!(springs > 0.0))
        fail("simulation.substeps",
             "\"auto\": explicit_euler has no stable time step in the estimate without "
             "cloth.damping or cloth.spring_damping (each spring mode grows by sqrt(1 + (omega "
             "dt)^2) a step; relative_damping is not in the estimate): give cloth.damping or "
             "cloth.spring_damping, a fixed simulation.substeps, or use velocity_verlet");
    const double limit = std::min(springs, cloth_->aeroTimeStep(dt));
    if (!(limit > 0.0)) fail("simulation.substeps", "\"auto\": no stable time step exists");
    const double needed = std::ceil(dt / (kAutoSubstepMargin * limit));
    if (!(needed <= static_cast<double>(kMaxSubsteps))) {
        // The time step "auto" can take: kMaxSubsteps steps within the margin, rounded down.
        const double most = kMaxSubsteps * kAutoSubstepMargin * limit;
        const std::string largest = formatDown(most, 3);
        const bool aeroBinds = cloth_->aeroTimeStep(dt) < springs;
        fail("simulation.substeps",
             "\"auto\" would need " + num(needed) + " sub-steps of the " + num(dt) +
                 " s time step (the stable limit of " +
                 (aeroBinds ? std::string("the explicit drag and lift, which every integrator "
                                          "takes explicitly,")
                            : std::string(toString(scene_.cloth.integrator))) +
                 " for this cloth is " + num(limit) + " s), more than the limit of " +
                 std::to_string(kMaxSubsteps) + ": lower simulation.time_step to " + largest +
                 " s or less" +
                 (aeroBinds ? std::string(", or use a thinner fluid (cloth.air.density) or a "
                                          "heavier cloth")
                            : std::string(", or use implicit_euler")));
    }
    scene_.substeps = std::max(1, static_cast<int>(needed));
}

void Simulation::warnStiffSpot() {
    // A few particles far stiffer for their mass than the rest (a sliver triangle, two
    // vertices nearly one) set the automatic sub-steps, and so the cost of every step. The
    // rest of the cloth: its bound with the stiffest 1 % of the free particles held still.
    if (!scene_.autoSubsteps || scene_.substeps < 2) return;
    const auto& topo = cloth_->topology();
    const std::vector<double> local =
        localAngularFrequencies(topo, cloth_->stiffness(), cloth_->inverseMasses());
    std::vector<double> free;
    for (std::size_t i = 0; i < local.size(); ++i)
        if (cloth_->inverseMasses()[i] > 0.0) free.push_back(local[i]);
    if (free.size() < 2) return;
    const auto k = static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(free.size() - 1));
    std::nth_element(free.begin(), free.begin() + k, free.end());
    const double p99 = free[static_cast<std::size_t>(k)];
    const auto half = static_cast<std::ptrdiff_t>(free.size() / 2);
    std::nth_element(free.begin(), free.begin() + half, free.end());
    const double median = free[static_cast<std::size_t>(half)];
    // Held still: the stiffest 1 %, and on a small mesh every particle beyond twice the
    // median (a short edge has two stiff ends; of 77 particles the top 1 % is one of them,
    // and the estimate said 80 sub-steps where the mesh without the sliver takes 12: review
    // 17). More than 1 % of the particles (and more than eight) is not a spot but the mesh's
    // grading (a disc's fan of 128 segments, a strip meshed finer): no warning.
    const double threshold = std::min(p99, 2.0 * median);
    std::vector<double> restInvMass = cloth_->inverseMasses();
    std::size_t held = 0;
    Index stiffest = 0;
    for (std::size_t i = 0; i < local.size(); ++i) {
        if (local[i] > local[stiffest]) stiffest = static_cast<Index>(i);
        if (restInvMass[i] > 0.0 && local[i] > threshold) {
            restInvMass[i] = 0.0;
            ++held;
        }
    }
    if (held == 0 || held > std::max<std::size_t>(8, free.size() / 100)) return;
    const double omegaRest = estimateMaxAngularFrequency(topo, cloth_->stiffness(), restInvMass);
    // The sub-steps the rest would ask for, as chooseSubsteps counts them.
    const double dt = scene_.timeStep;
    const double restLimit = std::min(springsTimeStep(*cloth_, scene_.cloth.integrator, omegaRest),
                                      cloth_->aeroTimeStep(dt));
    const int without =
        std::max(1, static_cast<int>(std::ceil(dt / (kAutoSubstepMargin * restLimit))));
    if (!(kStiffSpotRatio * without <= scene_.substeps)) return;
    double shortest = std::numeric_limits<double>::infinity();
    Index other = stiffest;
    for (Index e = topo.adjacencyOffsets()[stiffest]; e < topo.adjacencyOffsets()[stiffest + 1];
         ++e)
        if (const double l = topo.springs()[topo.adjacentSprings()[e]].restLength; l < shortest) {
            shortest = l;
            other = topo.adjacentParticles()[e];
        }
    warnings_.push_back(
        std::to_string(held) + " of the cloth's " + std::to_string(free.size()) +
        " free particles set its stable time step: \"auto\" takes " +
        std::to_string(scene_.substeps) + " cloth sub-steps a step where about " +
        std::to_string(without) + " would do for the rest of the cloth. The stiffest, particle " +
        std::to_string(stiffest) + ", has springs reaching " + num(local[stiffest]) +
        " rad/s against " + num(median) + " for the median particle (its shortest spring " +
        num(shortest) + (scene_.unitsPerMetre == 1.0 ? " m" : " units") + ", to particle " +
        std::to_string(other) +
        "): weld vertices a hair apart (a larger weld_tolerance) or remove the sliver "
        "triangles");
}

void Simulation::warnLongRun() {
    // Each factor can be within its limit while their product asks for days: say so before
    // the run starts, at the cost of drape's cheapest steps (a lower bound of the time).
    const double particleSteps = static_cast<double>(cloth_->particleCount()) *
                                 static_cast<double>(scene_.stepCount()) * scene_.substeps;
    const double leastSeconds = particleSteps * kLeastSecondsPerParticleStep;
    if (leastSeconds <= kLongRunSeconds) return;
    warnings_.push_back(
        "the run is " + num(particleSteps) + " particle-steps (" +
        std::to_string(cloth_->particleCount()) + " particles x " +
        std::to_string(scene_.stepCount()) + " steps x " + std::to_string(scene_.substeps) +
        " cloth sub-steps): at least " + num(leastSeconds / 3600.0) +
        " hours at drape's cheapest steps (" + num(kLeastSecondsPerParticleStep * 1e9) +
        " ns a particle-step on one core, no contacts); shorten simulation.duration, coarsen "
        "the cloth, or lower its stiffness to need fewer sub-steps");
}

void Simulation::fail(const std::string& path, const std::string& what) const {
    throw SceneError(origin(scene_) + ": " + path + ": " + what);
}

std::vector<Index>
Simulation::resolve(const ParticleSelector& sel, const std::vector<Index>& v2p,
                    const std::map<std::string, std::vector<Index>>& groups) const {
    const std::size_t n = cloth_->particleCount();
    std::vector<unsigned char> chosen(n, 0);
    for (std::size_t k = 0; k < sel.indices.size(); ++k) {
        const Index i = sel.indices[k];
        // Indices count welded mesh vertices (see SCENES.md); the topology may drop unused ones.
        if (i >= v2p.size() || v2p[i] >= n)
            fail(sel.path + ".indices[" + std::to_string(k) + "]",
                 "particle " + std::to_string(i) + " is out of range (the cloth has " +
                     std::to_string(n) + " particles)");
        chosen[v2p[i]] = 1;
    }
    for (std::size_t k = 0; k < sel.gridCells.size(); ++k) {
        const auto& spec = scene_.sheet->spec;
        const auto [r, c] = sel.gridCells[k];
        if (r >= spec.rows || c >= spec.cols)
            fail(sel.path + ".grid[" + std::to_string(k) + "]",
                 "(" + std::to_string(r) + ", " + std::to_string(c) + ") is outside the " +
                     std::to_string(spec.rows) + " x " + std::to_string(spec.cols) + " sheet");
        chosen[v2p[sheetIndex(spec, r, c)]] = 1;
    }
    if (sel.box) {
        std::size_t hits = 0;
        for (std::size_t i = 0; i < n; ++i) {
            const Vec3& x = cloth_->positions()[i];
            if ((x.array() >= (*sel.box)[0].array()).all() &&
                (x.array() <= (*sel.box)[1].array()).all()) {
                chosen[i] = 1;
                ++hits;
            }
        }
        if (hits == 0) fail(sel.path + ".box", "contains no particle of the cloth");
    }
    for (std::size_t k = 0; k < sel.groups.size(); ++k) {
        auto it = groups.find(sel.groups[k]);
        if (it == groups.end()) {
            std::string names;
            for (const auto& [name, idx] : groups)
                names += (names.empty() ? "" : ", ") + ("\"" + name + "\"");
            fail(sel.path + ".groups[" + std::to_string(k) + "]",
                 "the mesh has no group \"" + sel.groups[k] + "\"" +
                     (names.empty() ? std::string(" (it has no named groups)")
                                    : " (it has " + names + ")"));
        }
        for (Index i : it->second)
            if (i < v2p.size() && v2p[i] < n) chosen[v2p[i]] = 1;
    }
    std::vector<Index> out;
    for (std::size_t i = 0; i < n; ++i)
        if (chosen[i]) out.push_back(static_cast<Index>(i));
    return out;
}

void Simulation::applyWind() {
    if (!scene_.wind) return;
    const double t = time();
    const WindDesc& w = *scene_.wind;
    cloth_->setWind(w.velocity + w.gustAmplitude * std::sin(2.0 * kPi * w.gustFrequency * t));
}

double Simulation::time() const {
    return static_cast<double>(steps_) * scene_.timeStep;
}

void Simulation::step() {
    const double dt = scene_.timeStep;
    try {
        if (world_) {
            world_->step(time(), dt); // the world sub-steps the cloth (scene_.substeps)
        } else {
            const int n = scene_.substeps;
            for (int k = 0; k < n; ++k)
                cloth_->step(dt / n);
        }
    } catch (const drape::Error& e) {
        const std::string where = origin(scene_) + ": step " + std::to_string(steps_ + 1) +
                                  " (t = " + num(time()) + " s)";
        if (e.code() == ErrorCode::UnstableTimeStep && !scene_.autoSubsteps) {
            // In the file's own terms: the count simulation.substeps must have for its
            // time_step (the cloth's message counts sub-steps of one cloth step, or names the
            // C++ settings the runner sets; review 16).
            const double limit = cloth_->stableTimeStep();
            const double h = dt / scene_.substeps;
            const std::string steps = "the cloth steps of " + num(h) + " s (simulation.time_step " +
                                      num(dt) + " s in " + std::to_string(scene_.substeps) +
                                      " sub-step" + (scene_.substeps == 1 ? "" : "s") + ")";
            // A count as digits (in floating point beyond a long long).
            const auto count = [](double n) {
                const double c = std::ceil(n);
                return c < 1e15 ? std::to_string(static_cast<long long>(c)) : num(c);
            };
            if (h > limit)
                throw StepError(where + " failed: " + steps + " exceed the stability limit " +
                                formatDown(limit) + " s of " + toString(scene_.cloth.integrator) +
                                " for this cloth: set simulation.substeps to at least " +
                                count(dt / limit) +
                                ", or to \"auto\" to choose them from the stability estimate "
                                "(cloth: " +
                                e.what() + ")");
            // The drag's limit at the cloth's speed of the moment: a fixed count that was
            // stable at the start can be outrun as the cloth speeds up against the air, and a
            // count for this speed alone is outrun again a few steps on (review 19: five
            // refusals in a row when followed): the count for twice the speed.
            if (const double drag = cloth_->aeroTimeStep(h); h > drag)
                throw StepError(
                    where + " failed: " + steps + " exceed the stability limit " +
                    formatDown(drag) +
                    " s of the explicit drag and lift at the cloth's speed against the air now "
                    "(up to " +
                    num(cloth_->aeroSpeedBound(h)) +
                    " m/s): set simulation.substeps to \"auto\" (each step is then split as the "
                    "cloth's speed asks), or to at least " +
                    count(2.0 * dt / drag) +
                    " (twice this speed; a count holds only up to a speed), or use a thinner "
                    "fluid (cloth.air.density) or a heavier cloth (cloth: " +
                    e.what() + ")");
        }
        throw StepError(where + " failed: " + e.what());
    }
    ++steps_;
    applyWind();
}

std::size_t Simulation::contactCount() const {
    return world_ ? world_->contactCount() : 0;
}

void Simulation::overflow(const std::string& what) const {
    throw StepError(origin(scene_) + ": step " + std::to_string(steps_) + " (t = " + num(time()) +
                    " s): " + what +
                    "; the simulation overflowed (the state grew without bound: a time step "
                    "beyond the stability limit, or forces far too large), and nothing "
                    "non-finite is written");
}

FrameStats Simulation::stats() const {
    FrameStats s;
    s.time = time();
    s.steps = steps_;
    s.maxStrain = cloth_->maxStrain();
    s.meanStrain = cloth_->meanStrain();
    s.kineticEnergy = cloth_->kineticEnergy();
    // Every value written (CSV, summary, OBJ in single precision, frames) must be finite:
    // positions within float range, velocities and statistics finite.
    constexpr double kFloatMax = static_cast<double>(std::numeric_limits<float>::max());
    double lowest = std::numeric_limits<double>::infinity();
    const Vec3List& x = cloth_->positions();
    const Vec3List& v = cloth_->velocities();
    for (std::size_t i = 0; i < x.size(); ++i) {
        if (!(x[i].cwiseAbs().maxCoeff() <= kFloatMax))
            overflow("particle " + std::to_string(i) + " is at (" + num(x[i].x()) + ", " +
                     num(x[i].y()) + ", " + num(x[i].z()) +
                     ") m, beyond the range of the single-precision output");
        // Beyond float's range too: a limiter holds the positions of a cloth whose velocities
        // grow without bound (a flag with reject_unstable_time_step off reached 1e81 m/s with
        // every position in place; review 19).
        if (!(v[i].cwiseAbs().maxCoeff() <= kFloatMax))
            overflow("the velocity of particle " + std::to_string(i) + " is (" + num(v[i].x()) +
                     ", " + num(v[i].y()) + ", " + num(v[i].z()) +
                     ") m/s, beyond the range of the single-precision output");
        lowest = std::min(lowest, x[i].dot(up_));
    }
    s.lowestPoint = lowest;
    s.contacts = contactCount();
    const std::pair<const char*, double> values[] = {{"the kinetic energy", s.kineticEnergy},
                                                     {"the largest strain", s.maxStrain},
                                                     {"the mean strain", s.meanStrain},
                                                     {"the lowest point", s.lowestPoint}};
    for (const auto& [name, value] : values)
        if (!std::isfinite(value)) overflow(std::string(name) + " is " + num(value));
    return s;
}

TriangleMesh Simulation::clothMesh() const {
    TriangleMesh m;
    m.vertices = cloth_->positions();
    m.triangles = cloth_->topology().triangles();
    return m;
}

std::vector<BodyView> Simulation::bodies() const {
    std::vector<BodyView> out;
    if (!world_) return out;
    for (std::size_t i = 0; i < scene_.rigidBodies.size(); ++i) {
        BodyView v;
        v.name = scene_.rigidBodies[i].name;
        v.transform = scene_.rigidBodies[i].shape.kind == ShapeKind::Plane
                          ? Eigen::Matrix4f::Identity() // drawn in world space
                          : world_->transform(i);
        v.meshes = &bodyMeshes_[i];
        out.push_back(v);
    }
    return out;
}

std::vector<DrawMesh> Simulation::drawMeshes() const {
    std::vector<DrawMesh> out;
    out.push_back(toDrawMesh(cloth_->positions(), cloth_->topology().triangles(), scene_.frontColor,
                             scene_.backColor));
    for (const BodyView& b : bodies()) {
        for (const DrawMesh& m : *b.meshes) {
            out.push_back(m);
            out.back().model = b.transform;
        }
    }
    return out;
}

namespace {
std::size_t findBody(const SceneDesc& s, const std::string& name) {
    for (std::size_t i = 0; i < s.rigidBodies.size(); ++i)
        if (s.rigidBodies[i].name == name) return i;
    throw SceneError(origin(s) + ": no rigid body named \"" + name + "\"");
}
} // namespace

Vec3 Simulation::bodyPosition(const std::string& name) const {
    const std::size_t i = findBody(scene_, name);
    if (!world_) return scene_.rigidBodies[i].position;
    return world_->transform(i).block<3, 1>(0, 3).cast<double>();
}

Vec3 Simulation::bodyVelocity(const std::string& name) const {
    const std::size_t i = findBody(scene_, name);
    return world_ ? world_->velocity(i) : Vec3::Zero();
}

void Simulation::launchBody(const std::string& name, const Vec3& position, const Vec3& velocity) {
    const std::size_t i = findBody(scene_, name);
    if (scene_.rigidBodies[i].motion != MotionKind::Dynamic)
        throw SceneError(origin(scene_) + ": rigid body \"" + name + "\" is not dynamic");
    if (!world_) throw SceneError(origin(scene_) + ": no rigid world");
    world_->launch(i, position, velocity);
}

std::string Simulation::worldDescription() const {
    return world_ ? world_->description() : std::string("cloth only");
}

} // namespace drape::samples
