// Report 1: drape against Bullet's soft bodies on the same scenes.
//
// Every engine gets the same mesh (vertex i = particle i = node i), the same particle masses,
// the same pins, the same gravity and the same static colliders:
//  - drape: Velocity-Verlet with and without the stress-ordered limiter, in a Bullet world
//    (drape::bullet) for the colliders.
//  - btSoftBody in a btSoftRigidDynamicsWorld, made with btSoftBodyHelpers::CreateFromTriMesh
//    (one link per unique triangle edge, exactly drape's springs), m_kLST = 1, sweeps of
//    m_cfg.piterations and of sub-steps. Its "stiffness" kLST is a unitless [0, 1]
//    position-correction factor, not N/m, so the stretch it reaches depends on the
//    iteration count and sub-steps, not on k = 20 N/m.
//  - Bullet's deformable world (btDeformableMultiBodyDynamicsWorld, implicit) with
//    btDeformableMassSpringForce at the same k = 20 N/m and btDeformableGravityForce.
#include "drape_reports/engines.hpp"
#include "drape_reports/reports.hpp"
#include "drape_reports/scenes.hpp"

#include "colliders.hpp"

#include <drape/bullet/convert.hpp>
#include <drape/error.hpp>
#include <drape/strain_limit.hpp>
#include <drape_samples/render.hpp>

#include <BulletSoftBody/btDeformableBodySolver.h>
#include <BulletSoftBody/btDeformableGravityForce.h>
#include <BulletSoftBody/btDeformableMassSpringForce.h>
#include <BulletSoftBody/btDeformableMultiBodyConstraintSolver.h>
#include <BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

namespace drape::reports {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

using bullet::toBt;

using Engine = ClothEngine;

class DrapeEngine : public Engine {
  public:
    DrapeEngine(const ClothScene& sc, LimiterKind limiter)
        : world_(sc, clothSettings(sc, IntegratorKind::VelocityVerlet, limiter)), dt_(sc.timeStep) {
    }
    void step() override { world_.step(dt_); }
    void state(std::vector<Vec3>& x, std::vector<Vec3>& v) const override {
        x = world_.cloth().positions();
        v = world_.cloth().velocities();
    }
    std::size_t links() const override { return world_.cloth().topology().springCount(); }

  private:
    DrapeWorld world_;
    double dt_;
};

/// Builds the soft body from the scene's mesh: same vertices, triangles, masses and pins.
btSoftBody* makeSoftBody(btSoftBodyWorldInfo& info, const ClothScene& sc) {
    std::vector<btScalar> verts;
    for (const Vec3& v : sc.mesh.vertices) {
        verts.push_back(btScalar(v.x()));
        verts.push_back(btScalar(v.y()));
        verts.push_back(btScalar(v.z()));
    }
    std::vector<int> tris;
    for (const Triangle& t : sc.mesh.triangles) {
        for (Index i : t)
            tris.push_back(static_cast<int>(i));
    }
    btSoftBody* psb = btSoftBodyHelpers::CreateFromTriMesh(
        info, verts.data(), tris.data(), static_cast<int>(sc.mesh.triangles.size()), false);
    for (int i = 0; i < psb->m_nodes.size(); ++i)
        psb->setMass(i, btScalar(sc.particleMass));
    for (Index p : sc.pins)
        psb->setMass(static_cast<int>(p), 0.0f);
    psb->m_materials[0]->m_kLST = 1.0f;
    psb->getCollisionShape()->setMargin(btScalar(sc.thickness));
    psb->m_cfg.kCHR = 1.0f;
    psb->m_cfg.kDF = btScalar(sc.colliders.empty() ? 0.2 : sc.colliders.front().friction);
    return psb;
}

void softState(const btSoftBody* psb, std::vector<Vec3>& x, std::vector<Vec3>& v) {
    const int n = psb->m_nodes.size();
    x.resize(static_cast<std::size_t>(n));
    v.resize(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
        const auto& nd = psb->m_nodes[i];
        x[static_cast<std::size_t>(i)] = Vec3(nd.m_x.x(), nd.m_x.y(), nd.m_x.z());
        v[static_cast<std::size_t>(i)] = Vec3(nd.m_v.x(), nd.m_v.y(), nd.m_v.z());
    }
}

class SoftBodyEngine : public Engine {
  public:
    SoftBodyEngine(const ClothScene& sc, int piterations, int substeps)
        : substeps_(substeps), dt_(sc.timeStep) {
        config_ = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
        dispatcher_ = std::make_unique<btCollisionDispatcher>(config_.get());
        broadphase_ = std::make_unique<btDbvtBroadphase>();
        solver_ = std::make_unique<btSequentialImpulseConstraintSolver>();
        world_ = std::make_unique<btSoftRigidDynamicsWorld>(dispatcher_.get(), broadphase_.get(),
                                                            solver_.get(), config_.get());
        world_->setGravity(toBt(sc.gravity));
        btSoftBodyWorldInfo& info = world_->getWorldInfo();
        info.m_gravity = toBt(sc.gravity);
        info.air_density = 0.0f;
        // The sparse SDF's cells must suit the scene's scale (spacing 10), not Bullet's metre
        // default of 0.25.
        info.m_sparsesdf.setDefaultVoxelsz(btScalar(0.25 * sc.sheet.spacing));
        info.m_sparsesdf.Reset();
        colliders_.build(world_.get(), sc.colliders, 0.0f);
        body_.reset(makeSoftBody(info, sc));
        body_->m_cfg.piterations = piterations;
        // Velocity damping per sub-step: v *= (1 - kDP); C_d / m per second.
        body_->m_cfg.kDP = btScalar(sc.damping / sc.particleMass * dt_ / substeps);
        world_->addSoftBody(body_.get());
    }
    ~SoftBodyEngine() override {
        world_->removeSoftBody(body_.get());
        colliders_.remove(world_.get());
    }
    void step() override {
        const btScalar h = btScalar(dt_ / substeps_);
        for (int i = 0; i < substeps_; ++i)
            world_->stepSimulation(h, 0);
    }
    void state(std::vector<Vec3>& x, std::vector<Vec3>& v) const override {
        softState(body_.get(), x, v);
    }
    std::size_t links() const override { return static_cast<std::size_t>(body_->m_links.size()); }

  private:
    int substeps_;
    double dt_;
    std::unique_ptr<btSoftBodyRigidBodyCollisionConfiguration> config_;
    std::unique_ptr<btCollisionDispatcher> dispatcher_;
    std::unique_ptr<btDbvtBroadphase> broadphase_;
    std::unique_ptr<btSequentialImpulseConstraintSolver> solver_;
    std::unique_ptr<btSoftRigidDynamicsWorld> world_;
    StaticColliders colliders_;
    std::unique_ptr<btSoftBody> body_;
};

class DeformableEngine : public Engine {
  public:
    explicit DeformableEngine(const ClothScene& sc) : dt_(sc.timeStep) {
        config_ = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
        dispatcher_ = std::make_unique<btCollisionDispatcher>(config_.get());
        broadphase_ = std::make_unique<btDbvtBroadphase>();
        bodySolver_ = std::make_unique<btDeformableBodySolver>();
        solver_ = std::make_unique<btDeformableMultiBodyConstraintSolver>();
        solver_->setDeformableSolver(bodySolver_.get());
        world_ = std::make_unique<btDeformableMultiBodyDynamicsWorld>(
            dispatcher_.get(), broadphase_.get(), solver_.get(), config_.get(), bodySolver_.get());
        world_->setGravity(toBt(sc.gravity));
        btSoftBodyWorldInfo& info = world_->getWorldInfo();
        info.m_gravity = toBt(sc.gravity);
        info.air_density = 0.0f;
        info.m_sparsesdf.setDefaultVoxelsz(btScalar(0.25 * sc.sheet.spacing));
        info.m_sparsesdf.Reset();
        colliders_.build(world_.get(), sc.colliders, 0.0f);
        body_.reset(makeSoftBody(info, sc));
        // Node (SDF_RD) and face (SDF_RDF) contacts: with node contacts alone the cloth fell
        // through the desk in our tests.
        body_->m_cfg.collisions = btSoftBody::fCollision::SDF_RD | btSoftBody::fCollision::SDF_RDF;
        world_->addSoftBody(body_.get());
        // Hooke springs at drape's k [N/m]; its damping acts along the springs (it has no
        // per-particle drag), with drape's C_d as the coefficient.
        spring_ = std::make_unique<btDeformableMassSpringForce>(btScalar(sc.stiffness),
                                                                btScalar(sc.damping), true);
        gravity_ = std::make_unique<btDeformableGravityForce>(toBt(sc.gravity));
        world_->addForce(body_.get(), spring_.get());
        world_->addForce(body_.get(), gravity_.get());
        world_->setImplicit(true);
        // With Bullet 3.24's default (Lagrange-multiplier contacts, no projection) the implicit
        // solve leaves the nodes where they are: a two-triangle cloth under gravity does not
        // move. The projection path is the one that integrates.
        world_->setUseProjection(true);
    }
    ~DeformableEngine() override {
        world_->removeSoftBody(body_.get());
        colliders_.remove(world_.get());
        world_.reset();
    }
    void step() override { world_->stepSimulation(btScalar(dt_), 0); }
    void state(std::vector<Vec3>& x, std::vector<Vec3>& v) const override {
        softState(body_.get(), x, v);
    }
    std::size_t links() const override { return static_cast<std::size_t>(body_->m_links.size()); }

  private:
    double dt_;
    std::unique_ptr<btSoftBodyRigidBodyCollisionConfiguration> config_;
    std::unique_ptr<btCollisionDispatcher> dispatcher_;
    std::unique_ptr<btDbvtBroadphase> broadphase_;
    std::unique_ptr<btDeformableBodySolver> bodySolver_;
    std::unique_ptr<btDeformableMultiBodyConstraintSolver> solver_;
    StaticColliders colliders_;
    std::unique_ptr<btSoftBody> body_;
    std::unique_ptr<btDeformableMassSpringForce> spring_;
    std::unique_ptr<btDeformableGravityForce> gravity_;
    std::unique_ptr<btDeformableMultiBodyDynamicsWorld> world_;
};

} // namespace

std::unique_ptr<ClothEngine> makeDrapeEngine(const ClothScene& scene, LimiterKind limiter) {
    return std::make_unique<DrapeEngine>(scene, limiter);
}
std::unique_ptr<ClothEngine> makeSoftBodyEngine(const ClothScene& scene, int piterations,
                                                int substeps) {
    return std::make_unique<SoftBodyEngine>(scene, piterations, substeps);
}
std::unique_ptr<ClothEngine> makeDeformableEngine(const ClothScene& scene) {
    return std::make_unique<DeformableEngine>(scene);
}

namespace {

struct Config {
    std::string engine;
    std::string config;
    std::string key; ///< short name for files
    int piterations = 0, substeps = 1;
    LimiterKind limiter = LimiterKind::None;
    bool render = false; ///< in the side-by-side image
};

std::unique_ptr<Engine> makeEngine(const Config& c, const ClothScene& sc) {
    if (c.engine == "drape") return makeDrapeEngine(sc, c.limiter);
    if (c.engine == "btSoftBody") return makeSoftBodyEngine(sc, c.piterations, c.substeps);
    return makeDeformableEngine(sc);
}

struct SceneRun {
    ClothScene scene;
    double duration = 0.0;
    int repeats = 1;
    double deformableDuration = 0.0; ///< shorter for the largest sheet
};

bool finiteAll(const std::vector<Vec3>& x) {
    for (const Vec3& p : x) {
        if (!p.allFinite()) return false;
    }
    return true;
}

/// Runs one configuration; fills the row and the final positions.
CompareRow runOne(const Config& c, const SceneRun& sr, int repeats, std::vector<Vec3>& finalX) {
    const ClothScene& sc = sr.scene;
    CompareRow row;
    row.scene = sc.name;
    row.engine = c.engine;
    row.config = c.config;
    row.particles = sc.mesh.vertices.size();
    const double duration = c.engine == "btDeformable" ? sr.deformableDuration : sr.duration;
    const long steps = std::lround(duration / sc.timeStep);
    auto topo = ClothTopology::build(sc.mesh);
    const double diameter = sc.sheet.spacing * (sc.sheet.rows + sc.sheet.cols);
    std::vector<double> perRun;
    for (int rep = 0; rep < repeats; ++rep) {
        const bool measure = rep == 0;
        std::unique_ptr<Engine> engine = makeEngine(c, sc);
        row.links = engine->links();
        std::vector<Vec3> x, v;
        std::vector<double> kinetic;
        double wall = 0.0;
        long done = 0;
        try {
            for (long i = 0; i < steps; ++i) {
                const double t0 = now();
                engine->step();
                wall += now() - t0;
                ++done;
                if (!measure) continue;
                engine->state(x, v);
                if (!finiteAll(x) || !finiteAll(v)) {
                    row.blewUp = true;
                    row.note = "non-finite state at t = " +
                               fmt(static_cast<double>(i + 1) * sc.timeStep, 3) + " s";
                    break;
                }
                double ke = 0.0;
                for (std::size_t p = 0; p < v.size(); ++p)
                    ke += 0.5 * sc.particleMass * v[p].squaredNorm();
                for (Index p : sc.pins)
                    ke -= 0.5 * sc.particleMass * v[p].squaredNorm();
                kinetic.push_back(ke);
                const double maxS = maxSpringStrain(*topo, x), meanS = meanSpringStrain(*topo, x);
                row.peakMaxStrain = std::max(row.peakMaxStrain, maxS);
                row.peakMeanStrain = std::max(row.peakMeanStrain, meanS);
                const Penetration pen = measurePenetration(sc.colliders, x);
                row.peakPenetration = std::max(row.peakPenetration, pen.depth);
                row.peakInside = std::max(row.peakInside, pen.inside);
                double far = 0.0;
                for (std::size_t p = 0; p < x.size(); ++p)
                    far = std::max(far, (x[p] - sc.mesh.vertices[p]).norm());
                if (far > 20.0 * diameter) {
                    row.blewUp = true;
                    row.note =
                        "diverged at t = " + fmt(static_cast<double>(i + 1) * sc.timeStep, 3) +
                        " s";
                    break;
                }
            }
        } catch (const Error& e) {
            row.blewUp = true;
            row.note = std::string("drape detected ") + toString(e.code()) + ": " + e.what();
        }
        if (done > 0) perRun.push_back(wall / static_cast<double>(done));
        if (!measure) continue;
        engine->state(x, v);
        finalX = x;
        if (finiteAll(x)) {
            row.finalMaxStrain = maxSpringStrain(*topo, x);
            row.finalMeanStrain = meanSpringStrain(*topo, x);
            row.finalInside = measurePenetration(sc.colliders, x).inside;
        } else {
            row.finalMaxStrain = row.finalMeanStrain = std::numeric_limits<double>::quiet_NaN();
        }
        row.finalKinetic =
            kinetic.empty() ? std::numeric_limits<double>::quiet_NaN() : kinetic.back();
        row.settleTime = kInf;
        if (!row.blewUp && !kinetic.empty()) {
            const double peak = *std::max_element(kinetic.begin(), kinetic.end());
            std::size_t last = kinetic.size();
            for (std::size_t i = kinetic.size(); i-- > 0;) {
                if (kinetic[i] > 1e-3 * peak) {
                    last = i;
                    break;
                }
            }
            if (last + 1 < kinetic.size())
                row.settleTime = static_cast<double>(last + 1) * sc.timeStep;
        }
        if (row.blewUp) break; // no point in timing a blow-up again
    }
    row.msPerStep = 1e3 * median(perRun);
    if (c.engine == "btDeformable" && sr.deformableDuration < sr.duration) {
        row.note += (row.note.empty() ? "" : "; ") + std::string("run shortened to ") +
                    fmt(sr.deformableDuration) + " s (cost)";
    }
    return row;
}

std::string yesNo(bool b) {
    return b ? "yes" : "no";
}

} // namespace

CompareResult runCompareReport(const CompareOptions& options, const Machine& machine) {
    CompareResult result;
    const bool quick = options.quick;
    std::vector<SceneRun> scenes;
    auto add = [&scenes](ClothScene sc, double duration, int repeats, double deformable) {
        SceneRun r;
        // The scene files' cameras at the report's render size (one image per engine).
        sc.camera.width = 360;
        sc.camera.height = 300;
        r.scene = std::move(sc);
        r.duration = duration;
        r.repeats = repeats;
        r.deformableDuration = deformable;
        scenes.push_back(std::move(r));
    };
    if (quick) {
        add(experiment1(12, 12), 1.0, 1, 1.0);
        add(experiment2(10, 20), 4.5, 1, 4.5);
        add(hangingSheet(16), 0.5, 1, 0.5);
        add(clothOnSphere(12), 3.0, 1, 3.0);
    } else {
        add(experiment1(), 10.0, 3, 10.0);
        add(experiment2(), 10.0, 2, 10.0);
        add(hangingSheet(64), 5.0, 1, 5.0);
        add(hangingSheet(128), 3.0, 1, 1.0);
        add(clothOnSphere(40), 8.0, 2, 8.0);
    }
    std::vector<Config> configs;
    configs.push_back({"drape", "Velocity-Verlet, stress-ordered limiter 10 %", "drape_vv_so", 0, 1,
                       LimiterKind::StressOrdered, true});
    configs.push_back(
        {"drape", "Velocity-Verlet, no limiter", "drape_vv", 0, 1, LimiterKind::None, true});
    for (auto [p, s] : std::vector<std::pair<int, int>>{{1, 1}, {4, 1}, {16, 1}, {1, 4}, {4, 4}}) {
        configs.push_back({"btSoftBody",
                           "piterations " + std::to_string(p) + ", " + std::to_string(s) +
                               " sub-step" + (s > 1 ? "s" : ""),
                           "softbody_p" + std::to_string(p) + "_s" + std::to_string(s), p, s,
                           LimiterKind::None, (p == 1 && s == 1) || (p == 4 && s == 4)});
    }
    configs.push_back({"btDeformable", "implicit, mass-spring k 20 N/m", "deformable", 0, 1,
                       LimiterKind::None, true});

    const auto& dir = options.outDir;
    std::filesystem::create_directories(dir);
    Table table({"scene", "engine", "config", "particles", "links", "ms_per_step",
                 "peak_max_strain", "peak_mean_strain", "final_max_strain", "final_mean_strain",
                 "peak_penetration", "peak_particles_inside", "final_particles_inside",
                 "settle_time_s", "final_kinetic_J", "blew_up", "note"});
    std::ostringstream sections;
    const bool render = options.render && samples::renderingAvailable();
    for (const SceneRun& sr : scenes) {
        std::vector<std::pair<std::string, std::vector<Vec3>>> finals;
        for (const Config& c : configs) {
            progress("compare: " + sr.scene.name + " " + c.engine + " " + c.config);
            std::vector<Vec3> finalX;
            const int repeats = sr.repeats;
            CompareRow row = runOne(c, sr, repeats, finalX);
            if (c.render) finals.emplace_back(c.engine + ": " + c.config, finalX);
            table.add({row.scene, row.engine, row.config, std::to_string(row.particles),
                       std::to_string(row.links), fmt(row.msPerStep, 4), fmt(row.peakMaxStrain, 4),
                       fmt(row.peakMeanStrain, 4), fmt(row.finalMaxStrain, 4),
                       fmt(row.finalMeanStrain, 4), fmt(row.peakPenetration, 4),
                       std::to_string(row.peakInside), std::to_string(row.finalInside),
                       std::isfinite(row.settleTime) ? fmt(row.settleTime, 4) : "not settled",
                       fmt(row.finalKinetic, 4), yesNo(row.blewUp), row.note});
            result.rows.push_back(row);
        }
        // Side-by-side renders of the final states.
        sections << "### " << sr.scene.title << "\n\n";
        if (render) {
            samples::OffscreenRenderer renderer(sr.scene.camera.width, sr.scene.camera.height);
            samples::Image strip;
            strip.width = 0;
            strip.height = sr.scene.camera.height;
            std::vector<samples::Image> images;
            for (const auto& f : finals) {
                std::vector<samples::DrawMesh> meshes;
                if (finiteAll(f.second) && !f.second.empty()) {
                    meshes.push_back(samples::toDrawMesh(f.second, sr.scene.mesh.triangles,
                                                         {0.80f, 0.18f, 0.16f},
                                                         {0.95f, 0.75f, 0.30f}));
                }
                auto cm = colliderMeshes(sr.scene.colliders, sr.scene.camera.target);
                meshes.insert(meshes.end(), cm.begin(), cm.end());
                images.push_back(renderer.render(sr.scene.camera, meshes, {0.93f, 0.94f, 0.96f}));
                strip.width += images.back().width + (images.size() > 1 ? 4 : 0);
            }
            strip.rgb.assign(static_cast<std::size_t>(strip.width) *
                                 static_cast<std::size_t>(strip.height) * 3u,
                             40);
            int x0 = 0;
            for (const auto& im : images) {
                for (int y = 0; y < im.height; ++y) {
                    std::copy_n(im.rgb.begin() + static_cast<std::ptrdiff_t>(y) * im.width * 3,
                                im.width * 3,
                                strip.rgb.begin() +
                                    (static_cast<std::ptrdiff_t>(y) * strip.width + x0) * 3);
                }
                x0 += im.width + 4;
            }
            const std::string png = "final_" + sr.scene.name + ".png";
            samples::writePng(dir / png, strip);
            sections << "![" << sr.scene.title << "](" << png << ")\n\nLeft to right: ";
            for (std::size_t i = 0; i < finals.size(); ++i)
                sections << (i ? "; " : "") << finals[i].first;
            sections << ".\n\n";
        } else {
            sections << "(renders skipped: "
                     << (options.render ? "this build has no OSMesa renderer" : "--no-render")
                     << ")\n\n";
        }
    }
    table.writeCsv(dir / "compare.csv");

    // Time-per-step plot: one group per scene, one bar per configuration.
    std::string plotWhy;
    bool plotted = false;
    {
        std::ostringstream dat;
        dat << "config";
        for (const SceneRun& sr : scenes)
            dat << "," << sr.scene.name;
        dat << "\n";
        for (const Config& c : configs) {
            std::string label = c.engine + " " + c.config;
            std::replace(label.begin(), label.end(), ',', ';'); // the CSV's separator
            dat << label;
            for (const SceneRun& sr : scenes) {
                for (const CompareRow& r : result.rows) {
                    if (r.scene == sr.scene.name && r.engine == c.engine && r.config == c.config) {
                        dat << "," << fmt(r.msPerStep, 5);
                    }
                }
            }
            dat << "\n";
        }
        writeText(dir / "ms_per_step.csv", dat.str());
        std::ostringstream g;
        g << "set terminal pngcairo size 1100,620 font 'sans,10'\nset output 'ms_per_step.png'\n"
          << "set datafile separator ','\nset style data histograms\nset style histogram clustered "
             "gap 1\n"
          << "set style fill solid 0.85 border -1\nset logscale y\nset ylabel 'wall time per 0.01 "
             "s step [ms]'\n"
          << "set title 'Time per step (median of repeated runs)'\nset key outside right top font "
             "',9'\n"
          << "set xtics rotate by -20\nset grid ytics\n"
          << "plot for [i=2:" << scenes.size() + 1
          << "] 'ms_per_step.csv' using i:xtic(1) title columnhead(i)\n";
        // Transposed: one cluster per configuration, one bar per scene.
        plotted = runGnuplot(dir, "ms_per_step", g.str(), plotWhy);
    }

    std::ostringstream md;
    md << "# drape against Bullet's soft bodies\n\n"
       << "Regenerate with `drape-report-compare" << (quick ? " --quick" : "")
       << "` (writes this folder "
       << "from scratch).\n\n"
       << machineMarkdown(machine) << "## Set-up\n\n"
       << "The scenes are the scene files of samples/scenes (the paper's experiments and "
          "cloth_on_sphere.json; the hanging sheets are Experiment I resized, the --quick sizes "
          "likewise: reports::resizedSheet).\n\n"
       << "Every engine gets the same triangle mesh (vertex i is particle i is node i), the same "
          "particle "
          "mass (0.5), the same pinned particles, gravity 9.8 and the same static colliders; the "
          "paper's "
          "units (spacing 10, k 20 N/m). Frame dt 0.01 s.\n\n"
       << "- **drape**: Velocity-Verlet, with and without the stress-ordered strain limiter (10 "
          "%), "
          "particle damping C_d and contact thickness of the scene file (C_d = 0.05 N s/m and "
          "thickness 1, Experiment II 0.15 N s/m and 2.5), contacts through drape::bullet.\n"
       << "- **btSoftBody** (btSoftRigidDynamicsWorld): btSoftBodyHelpers::CreateFromTriMesh on "
          "the same "
          "vertices and triangles; its links are the unique triangle edges, the same set as "
          "drape's springs "
          "(the link counts below match). Node masses set one by one, pins by setMass(node, 0), "
          "m_kLST = 1, kDP = C_d dt / m per sub-step (its velocity damping), margin = the "
          "thickness, kCHR 1, "
          "kDF = the collider's friction. Sweeps of m_cfg.piterations (1, 4, 16) and of sub-steps "
          "(1, 4). "
          "**Its stiffness is not a spring constant**: kLST is a unitless [0, 1] factor of a "
          "position "
          "correction, so the k = 20 N/m of the paper has no counterpart; how far the cloth "
          "stretches "
          "depends on piterations and sub-steps instead.\n"
       << "- **btDeformable** (btDeformableMultiBodyDynamicsWorld, implicit solve): "
          "btDeformableMassSpringForce(k = 20 N/m, damping C_d along the springs) and "
          "btDeformableGravityForce, SDF_RD contacts, setUseProjection(true) (with Bullet 3.24's "
          "default Lagrange-multiplier path the implicit solve does not move the nodes at all: a "
          "two-triangle cloth under gravity stays put).\n\n"
       << "Measured each step (outside the timed part): max and mean spring strain (l - L0) / L0, "
          "deepest penetration into a collider (signed distance < 0, without any thickness) and "
          "the "
          "number of particles inside, kinetic energy. 'Settle time' = from the step after which "
          "the "
          "kinetic energy stays below 0.1 % of its peak until the end of the run ('not settled' if "
          "it "
          "never does). 'Blew up' = a non-finite state, a particle more than 20 cloth sizes away, "
          "or a "
          "failure drape detected. Time per step = wall time of the engine's step alone, median "
          "over "
          "the repeated runs.\n\n"
       << "Reduced to keep the whole report under 10 minutes on this 2-core machine: ";
    for (const SceneRun& sr : scenes) {
        md << sr.scene.title << " " << fmt(sr.duration) << " s x " << sr.repeats << " run(s)"
           << (sr.deformableDuration < sr.duration
                   ? " (deformable world " + fmt(sr.deformableDuration) + " s)"
                   : "")
           << "; ";
    }
    md << "\n\n## Results\n\n";
    if (plotted)
        md << "![time per step](ms_per_step.png)\n\n";
    else
        md << "(time plot not drawn: " << plotWhy << ")\n\n";
    md << "| scene | engine | config | ms/step | max strain peak / end | mean strain peak / end | "
          "deepest penetration | inside peak / end | settle [s] | final KE [J] | blew up |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const CompareRow& r : result.rows) {
        md << "| " << r.scene << " | " << r.engine << " | " << r.config << " | "
           << fmt(r.msPerStep, 3) << " | " << fmt(r.peakMaxStrain, 3) << " / "
           << fmt(r.finalMaxStrain, 3) << " | " << fmt(r.peakMeanStrain, 3) << " / "
           << fmt(r.finalMeanStrain, 3) << " | " << fmt(r.peakPenetration, 3) << " | "
           << r.peakInside << " / " << r.finalInside << " | "
           << (std::isfinite(r.settleTime) ? fmt(r.settleTime, 3) : "not settled") << " | "
           << fmt(r.finalKinetic, 3) << " | " << (r.blewUp ? "**yes** " + r.note : "no") << " |\n";
    }
    // The speed ratio per scene: drape with the limiter against every btSoftBody set-up, with
    // both peak strains, so "faster at equal or smaller stretch" can be read off directly.
    {
        Table ratios({"scene", "btSoftBody_config", "btSoftBody_ms_per_step", "drape_ms_per_step",
                      "speed_ratio_btSoftBody_over_drape", "btSoftBody_peak_max_strain",
                      "drape_peak_max_strain", "drape_strain_le_btSoftBody", "btSoftBody_blew_up"});
        md << "\n## Speed ratio, drape against btSoftBody\n\n"
           << "drape = Velocity-Verlet with the stress-ordered limiter (10 %). Ratio = "
              "btSoftBody's "
              "time per step / drape's (above 1: drape is faster), both medians of the runs above, "
              "measured in this run. Peak max strain = the largest spring strain seen in the "
              "run.\n\n"
           << "| scene | btSoftBody config | btSoftBody ms/step | drape ms/step | ratio (x faster) "
              "| "
              "peak max strain btSoftBody / drape | drape's strain <= btSoftBody's |\n"
           << "|---|---|---|---|---|---|---|\n";
        for (const SceneRun& sr : scenes) {
            const CompareRow* dr = nullptr;
            for (const CompareRow& r : result.rows) {
                if (r.scene == sr.scene.name && r.engine == "drape" &&
                    r.config.find("stress-ordered") != std::string::npos) {
                    dr = &r;
                }
            }
            if (!dr) continue;
            for (const CompareRow& r : result.rows) {
                if (r.scene != sr.scene.name || r.engine != "btSoftBody") continue;
                const double ratio = dr->msPerStep > 0.0 ? r.msPerStep / dr->msPerStep : kInf;
                const bool lower = dr->peakMaxStrain <= r.peakMaxStrain;
                md << "| " << r.scene << " | " << r.config << (r.blewUp ? " (blew up)" : "")
                   << " | " << fmt(r.msPerStep, 3) << " | " << fmt(dr->msPerStep, 3) << " | "
                   << fmt(ratio, 3) << " | " << fmt(r.peakMaxStrain, 3) << " / "
                   << fmt(dr->peakMaxStrain, 3) << " | " << yesNo(lower) << " |\n";
                ratios.add({r.scene, r.config, fmt(r.msPerStep, 5), fmt(dr->msPerStep, 5),
                            fmt(ratio, 5), fmt(r.peakMaxStrain, 5), fmt(dr->peakMaxStrain, 5),
                            yesNo(lower), yesNo(r.blewUp)});
            }
        }
        ratios.writeCsv(dir / "speed_ratio.csv");
    }
    // Where each engine wins, computed from the rows (so it stays true when the numbers move).
    {
        std::ostringstream soft, drape;
        for (const SceneRun& sr : scenes) {
            const CompareRow* dr = nullptr;
            const CompareRow* fastSoft = nullptr;
            const CompareRow* stiffSoft = nullptr;
            const CompareRow* deform = nullptr;
            for (const CompareRow& r : result.rows) {
                if (r.scene != sr.scene.name) continue;
                if (r.engine == "drape" && r.config.find("stress-ordered") != std::string::npos)
                    dr = &r;
                if (r.engine == "btDeformable") deform = &r;
                if (r.engine == "btSoftBody" && !r.blewUp) {
                    // Fastest among the set-ups that stay a cloth (under 50 % stretch).
                    if (r.peakMaxStrain <= 0.5 && (!fastSoft || r.msPerStep < fastSoft->msPerStep))
                        fastSoft = &r;
                    if (!stiffSoft || r.peakMaxStrain < stiffSoft->peakMaxStrain) stiffSoft = &r;
                }
            }
            if (!dr || !stiffSoft) continue;
            if (!fastSoft) fastSoft = stiffSoft;
            const std::string name = sr.scene.title;
            if (fastSoft->msPerStep < dr->msPerStep) {
                soft << "- " << name << ": btSoftBody (" << fastSoft->config << ") steps in "
                     << fmt(fastSoft->msPerStep, 3) << " ms against drape's "
                     << fmt(dr->msPerStep, 3) << " ms with the limiter ("
                     << fmt(dr->msPerStep / fastSoft->msPerStep, 2)
                     << " x faster; the fastest btSoftBody set-up that stays under 50 % stretch), "
                        "peak stretch "
                     << fmt(100 * fastSoft->peakMaxStrain, 3) << " %.\n";
            } else {
                drape << "- " << name << ": drape with the limiter steps in "
                      << fmt(dr->msPerStep, 3)
                      << " ms, faster than the fastest btSoftBody set-up under 50 % stretch ("
                      << fastSoft->config << ", " << fmt(fastSoft->msPerStep, 3) << " ms).\n";
            }
            if (stiffSoft->peakMaxStrain < dr->peakMaxStrain) {
                soft << "- " << name << ": btSoftBody (" << stiffSoft->config
                     << ") never stretches more than " << fmt(100 * stiffSoft->peakMaxStrain, 3)
                     << " % (drape's limiter allows " << fmt(100 * dr->peakMaxStrain, 3)
                     << " %): an inextensible look, at " << fmt(stiffSoft->msPerStep, 3)
                     << " ms per step.\n";
            }
            if (fastSoft->peakInside < dr->peakInside) {
                soft << "- " << name << ": fewer particles inside colliders ("
                     << fastSoft->peakInside << " against drape's " << dr->peakInside << ").\n";
            } else if (dr->peakInside < fastSoft->peakInside) {
                drape << "- " << name << ": no deeper contact trouble: " << dr->peakInside
                      << " particles inside colliders at worst against " << fastSoft->peakInside
                      << " for btSoftBody (" << fastSoft->config << ", deepest "
                      << fmt(fastSoft->peakPenetration, 3) << ").\n";
            }
            bool drapeFailed = false;
            for (const CompareRow& r : result.rows) {
                drapeFailed =
                    drapeFailed || (r.scene == sr.scene.name && r.engine == "drape" && r.blewUp);
            }
            for (const CompareRow& r : result.rows) {
                if (r.scene == sr.scene.name && r.engine == "btSoftBody" && r.blewUp &&
                    !drapeFailed) {
                    drape << "- " << name << ": btSoftBody (" << r.config << ") blew up (" << r.note
                          << "); both drape configurations ran to the end.\n";
                }
            }
            if (deform && (deform->blewUp || deform->peakInside > dr->peakInside)) {
                drape << "- " << name << ": Bullet's deformable world at the same k: "
                      << (deform->blewUp ? "blew up (" + deform->note + ")"
                                         : std::to_string(deform->peakInside) +
                                               " particles inside colliders, deepest " +
                                               fmt(deform->peakPenetration, 3))
                      << ", at " << fmt(deform->msPerStep, 3) << " ms per step.\n";
            }
        }
        md << "\n## Where btSoftBody wins\n\n"
           << (soft.str().empty() ? "- nowhere in these runs\n" : soft.str())
           << "\nbtSoftBody's strength is its position solver: a few iterations of kLST = 1 "
              "make links nearly inextensible at a low cost, and its stretch falls with every "
              "extra iteration or sub-step. What it does not offer is a physical stiffness: "
              "kLST has no unit, and the same cloth stretches differently at another "
              "piterations or time step, so its 'material' cannot be set from N/m or Young's "
              "modulus as the paper asks.\n\n"
           << "## Where drape wins\n\n"
           << (drape.str().empty() ? "- nowhere in these runs\n" : drape.str())
           << "\ndrape's springs are physical (N/m, from the fabric's E and thickness); its "
              "stretch "
              "is bounded by the limiter's 10 % whatever the time step, and the strain it "
              "reports is the strain of the material law; a step that would blow up is refused "
              "or detected and rolled back.\n";
    }
    md << "\nParticles and links (drape springs / btSoftBody links / deformable links): ";
    std::map<std::string, std::map<std::string, std::size_t>> counts;
    std::map<std::string, std::size_t> particles;
    for (const CompareRow& r : result.rows) {
        counts[r.scene][r.engine] = r.links;
        particles[r.scene] = r.particles;
    }
    for (auto& [scene, c] : counts) {
        md << scene << " " << particles[scene] << " particles, " << c["drape"] << " / "
           << c["btSoftBody"] << " / " << c["btDeformable"] << "; ";
    }
    md << "\n\nData: [compare.csv](compare.csv), [ms_per_step.csv](ms_per_step.csv), "
          "[speed_ratio.csv](speed_ratio.csv).\n\n"
       << "## Final states\n\n"
       << sections.str();
    writeText(dir / "report.md", md.str());
    return result;
}

} // namespace drape::reports
