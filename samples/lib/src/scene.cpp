// scene.cpp: strict parsing of JSON scene files into SceneDesc (format: samples/SCENES.md).
#include "drape_samples/scene.hpp"

#include "json_reader.hpp"

#include <drape/error.hpp>

#include <cmath>
#include <fstream>
#include <sstream>

namespace drape::samples {

using detail::Json;
using detail::JsonObject;
using detail::Limits;

std::size_t SceneDesc::stepCount() const {
    return static_cast<std::size_t>(std::llround(duration / timeStep));
}

namespace {

constexpr std::size_t kMaxListEntries = 1u << 20;

// The physical range of every number a scene holds (SCENES.md, "Ranges", lists the same).
// Wide enough for any real scene (the paper's 350 m sheets, millimetre meshes), narrow
// enough that no product of them overflows a double during a run.
constexpr Limits kCoordinate{-kMaxCoordinate, kMaxCoordinate, "m"};
constexpr Limits kDirection{-1e6, 1e6, ""};
constexpr Limits kSize{1e-6, 1e5, "m"};
constexpr Limits kSizeOrZero{0.0, 1e5, "m"};
constexpr Limits kScale{1e-6, 1e6, ""};
constexpr Limits kAngle{-1e6, 1e6, "degrees"};
constexpr Limits kParticleMass{1e-12, 1e6, "kg"};
constexpr Limits kTotalMass{1e-9, 1e9, "kg"};
constexpr Limits kStiffness{1e-9, 1e12, "N/m"};
constexpr Limits kYoungsModulus{1e-3, 1e13, "Pa"};
constexpr Limits kMaterialThickness{1e-7, 1.0, "m"};
constexpr Limits kDensity{1e-12, 1e5, "kg/m^3"}; // per cubic unit: 4e-4 kg/cm^3 for cotton
constexpr Limits kDamping{0.0, 1e9, "N s/m"};
constexpr Limits kRate{0.0, 1e6, "1/s"};
constexpr Limits kAirDensity{0.0, 1e4, "kg/m^3"};
constexpr Limits kCoefficient{0.0, 100.0, ""};
constexpr Limits kTimeStep{kMinTimeStep, kMaxTimeStep, "s"};
constexpr Limits kDuration{kMinTimeStep, kMaxDuration, "s"};
constexpr Limits kTime{0.0, 1e9, "s"};
constexpr Limits kGravity{-1e4, 1e4, "m/s^2"};
constexpr Limits kVelocity{-1e4, 1e4, "m/s"};
constexpr Limits kAngularVelocity{-1e4, 1e4, "rad/s"};
constexpr Limits kFrequency{0.0, 1e6, "Hz"};
constexpr Limits kBodyMass{1e-6, 1e9, "kg"};
constexpr Limits kUnitInterval{0.0, 1.0, ""};
constexpr Limits kPenaltyForce{0.0, 1e12, "N"};
constexpr Limits kCgTolerance{1e-16, 0.5, ""}; // below 1 (ImplicitSettings::cgTolerance)
constexpr Limits kMaxStrain{1e-6, 10.0, ""};
constexpr Limits kStrainTolerance{0.0, 10.0, ""};
constexpr Limits kToleranceStep{1e-9, 1e3, ""};
constexpr Limits kWarmStart{0.0, 1.0, "", false, true};
constexpr Limits kLongRangeSlack{1.0, 100.0, ""};
constexpr Limits kFov{0.0, 179.0, "degrees", true, true};
constexpr Limits kFps{kMinFps, kMaxFps, "1/s"};
constexpr Limits kWeldTolerance{0.0, 1e5, "m"};
constexpr Limits kUnitsPerMetre{1e-3, 1e3, ""};

MeshDesc parseMeshDesc(JsonObject o, const std::filesystem::path& baseDir, double unitsPerMetre) {
    o.keys(
        {"file", "scale", "rotation_deg", "translation", "weld_tolerance", "degenerate_triangles"});
    MeshDesc m;
    m.unitsPerMetre = unitsPerMetre;
    const std::string file = o.requireString("file");
    if (file.empty()) o.failKey("file", "must not be empty");
    m.file = std::filesystem::path(file);
    if (m.file.is_relative()) m.file = baseDir / m.file;
    if (const Json* s = o.find("scale")) {
        if (s->is_number())
            m.scale = Vec3::Constant(o.toNumber(*s, o.pathOf("scale"), kScale));
        else
            m.scale = o.toVec3(*s, o.pathOf("scale"), kScale);
    }
    m.rotationDeg = o.vec3("rotation_deg", m.rotationDeg, kAngle);
    m.translation = o.vec3("translation", m.translation, kCoordinate);
    if (const Json* w = o.find("weld_tolerance")) {
        // Negative: automatic, as when absent (the format documents -1); else a distance.
        const bool automatic = w->is_number() && w->get<double>() < 0.0;
        if (!automatic)
            m.weldTolerance = o.toNumber(*w, o.pathOf("weld_tolerance"), kWeldTolerance);
    }
    m.refuseDegenerate = o.choice("degenerate_triangles", "drop", {"drop", "refuse"}) == "refuse";
    o.finish();
    return m;
}

ParticleSelector parseSelector(JsonObject& o, bool isSheet) {
    ParticleSelector s;
    // The caller declared the object's keys (its own and "indices", "grid", "box", "groups").
    s.path = o.path();
    const Json& idx = o.array("indices", kMaxListEntries);
    for (std::size_t i = 0; i < idx.size(); ++i)
        s.indices.push_back(static_cast<Index>(o.toInteger(
            idx[i], o.pathOf("indices") + "[" + std::to_string(i) + "]", 0, 0xFFFFFFFELL)));
    const Json& grid = o.array("grid", kMaxListEntries);
    if (!grid.empty() && !isSheet)
        o.failKey("grid", "(row, col) pins need a generated sheet (cloth.sheet)");
    for (std::size_t i = 0; i < grid.size(); ++i) {
        const std::string p = o.pathOf("grid") + "[" + std::to_string(i) + "]";
        if (!grid[i].is_array() || grid[i].size() != 2) o.fail(p, "expected [row, col]");
        s.gridCells.push_back(
            {static_cast<Index>(o.toInteger(grid[i][0], p + "[0]", 0, 0xFFFFFFFELL)),
             static_cast<Index>(o.toInteger(grid[i][1], p + "[1]", 0, 0xFFFFFFFELL))});
    }
    if (auto box = o.optObject("box")) {
        box->keys({"min", "max"});
        const Vec3 lo = box->requireVec3("min", kCoordinate);
        const Vec3 hi = box->requireVec3("max", kCoordinate);
        for (int i = 0; i < 3; ++i)
            if (lo[i] > hi[i]) box->fail(box->pathOf("min"), "min must not exceed max on any axis");
        box->finish();
        s.box = std::array<Vec3, 2>{lo, hi};
    }
    const Json& groups = o.array("groups", 1024);
    if (!groups.empty() && isSheet)
        o.failKey("groups", "named groups come from a mesh file (cloth.mesh), not a sheet");
    for (std::size_t i = 0; i < groups.size(); ++i) {
        if (!groups[i].is_string())
            o.fail(o.pathOf("groups") + "[" + std::to_string(i) + "]", "expected a string");
        s.groups.push_back(groups[i].get<std::string>());
    }
    if (s.indices.empty() && s.gridCells.empty() && !s.box && s.groups.empty())
        o.fail(o.path(), "selects nothing: give indices, grid, box or groups");
    return s;
}

void parseCloth(JsonObject o, SceneDesc& sc, const std::filesystem::path& baseDir) {
    o.keys({"sheet", "mesh", "particle_mass", "total_mass", "mass_lumping", "stiffness", "material",
            "damping", "relative_damping", "spring_damping", "air", "front_color", "back_color"});
    const bool hasSheet = o.has("sheet");
    const bool hasMesh = o.has("mesh");
    if (hasSheet == hasMesh)
        o.fail(o.path(),
               "give exactly one of cloth.sheet (a generated sheet) or cloth.mesh (a file)");
    if (hasSheet) {
        JsonObject s = o.object("sheet");
        s.keys({"rows", "cols", "spacing", "origin", "u_axis", "v_axis"});
        SheetDesc d;
        d.spec.rows =
            static_cast<Index>(s.toInteger(s.require("rows"), s.pathOf("rows"), 2, 1 << 20));
        d.spec.cols =
            static_cast<Index>(s.toInteger(s.require("cols"), s.pathOf("cols"), 2, 1 << 20));
        if (static_cast<std::size_t>(d.spec.rows) * d.spec.cols > kMaxSceneParticles)
            s.fail(s.path(),
                   "rows x cols = " +
                       std::to_string(static_cast<std::size_t>(d.spec.rows) * d.spec.cols) +
                       " particles exceeds the limit of " + std::to_string(kMaxSceneParticles));
        d.spec.spacing = s.requireNumber("spacing", kSize);
        d.spec.origin = s.vec3("origin", Vec3::Zero(), kCoordinate);
        d.spec.uAxis = s.vec3("u_axis", Vec3::UnitX(), kDirection);
        d.spec.vAxis = s.vec3("v_axis", -Vec3::UnitY(), kDirection);
        if (d.spec.uAxis.norm() < 1e-12) s.failKey("u_axis", "must not be zero");
        if (d.spec.vAxis.norm() < 1e-12) s.failKey("v_axis", "must not be zero");
        if (d.spec.uAxis.normalized().cross(d.spec.vAxis.normalized()).norm() < 1e-6)
            s.failKey("v_axis", "must not be parallel to u_axis");
        // The sheet is a parallelogram: its corners are its extremes.
        const Vec3 u = d.spec.uAxis.normalized() * (d.spec.spacing * (d.spec.cols - 1));
        const Vec3 v = d.spec.vAxis.normalized() * (d.spec.spacing * (d.spec.rows - 1));
        for (const Vec3& corner : {d.spec.origin, Vec3(d.spec.origin + u), Vec3(d.spec.origin + v),
                                   Vec3(d.spec.origin + u + v)})
            if (!(corner.cwiseAbs().maxCoeff() <= kMaxCoordinate))
                s.fail(s.path(), "the sheet reaches (" + JsonObject::fmt(corner.x()) + ", " +
                                     JsonObject::fmt(corner.y()) + ", " +
                                     JsonObject::fmt(corner.z()) + "), outside the " +
                                     detail::describe(kCoordinate) +
                                     " coordinate range (origin, spacing x rows and cols)");
        s.finish();
        sc.sheet = d;
    } else {
        sc.mesh = parseMeshDesc(o.object("mesh"), baseDir, sc.unitsPerMetre);
    }

    ClothSettings& c = sc.cloth;
    // Absent values are ClothSettings' own defaults (a 200 g/m^2 cotton, automatic stiffness).
    c.particleMass = o.optNumber("particle_mass", kParticleMass);
    c.totalMass = o.optNumber("total_mass", kTotalMass);
    if (o.has("particle_mass") && o.has("total_mass"))
        o.failKey("total_mass", "give particle_mass or total_mass, not both");
    const std::string lump = o.choice("mass_lumping", "uniform", {"uniform", "area"});
    c.lumping = lump == "area" ? MassLumping::AreaLumped : MassLumping::Uniform;
    c.springStiffness = o.optNumber("stiffness", kStiffness);
    if (auto m = o.optObject("material")) {
        m->keys({"youngs_modulus", "thickness", "density"});
        c.material.youngsModulus = m->optNumber("youngs_modulus", kYoungsModulus);
        c.material.thickness = m->number("thickness", c.material.thickness, kMaterialThickness);
        c.material.density = m->number("density", c.material.density, kDensity);
        m->finish();
    }
    c.damping = o.number("damping", 0.0, kDamping);
    c.relativeDamping = o.number("relative_damping", drape::kDefaultRelativeDamping, kRate);
    c.springDamping = o.number("spring_damping", 0.0, kDamping);
    if (auto a = o.optObject("air")) {
        a->keys({"density", "drag_coefficient", "lift_coefficient"});
        // 1.2 kg/m^3, per cubic unit of the scene's length.
        const double u = sc.unitsPerMetre;
        // The range too: up to 10,000 kg/m^3 in the scene's unit (at units_per_metre 0.001,
        // kilometres, air is 1.2e9 kg per cubic unit, which the range in metres refused;
        // review 17).
        const Limits density =
            u == 1.0 ? kAirDensity
                     : Limits{0.0, kAirDensity.hi / (u * u * u), "kg per cubic scene unit"};
        c.aero.airDensity = a->number("density", 1.2 / (u * u * u), density);
        c.aero.dragCoefficient = a->number("drag_coefficient", 1.0, kCoefficient);
        c.aero.liftCoefficient = a->number("lift_coefficient", 0.0, kCoefficient);
        a->finish();
    }
    sc.frontColor = o.color("front_color", sc.frontColor);
    sc.backColor = o.color("back_color", sc.backColor);
    o.finish();
}

void parseSimulation(JsonObject o, SceneDesc& sc) {
    o.keys({"integrator", "time_step", "duration", "substeps", "gravity",
            "reject_unstable_time_step", "implicit"});
    const std::string integ = o.choice(
        "integrator", "velocity_verlet",
        {"velocity_verlet", "explicit_euler", "symplectic_euler", "rk4", "implicit_euler"});
    sc.cloth.integrator = integratorFromString(integ);
    sc.timeStep = o.number("time_step", sc.timeStep, kTimeStep);
    sc.duration = o.number("duration", sc.duration, kDuration);
    if (const Json* n = o.find("substeps")) {
        if (n->is_string()) {
            if (n->get<std::string>() != "auto")
                o.failKey("substeps", "expected an integer in [1, " + std::to_string(kMaxSubsteps) +
                                          "] or \"auto\", got \"" + n->get<std::string>() + "\"");
            sc.autoSubsteps = true;
        } else {
            sc.substeps = static_cast<int>(o.toInteger(*n, o.pathOf("substeps"), 1, kMaxSubsteps));
            sc.autoSubsteps = false;
        }
    }
    sc.cloth.gravity = o.vec3("gravity", sc.cloth.gravity, kGravity); // -9.81 m/s^2, in units
    sc.cloth.rejectUnstableTimeStep = o.boolean("reject_unstable_time_step", true);
    if (auto imp = o.optObject("implicit")) {
        imp->keys({"solver", "cg_tolerance", "cg_max_iterations"});
        const std::string solver = imp->choice("solver", "cg", {"cg", "ldlt"});
        sc.cloth.implicit.solver =
            solver == "ldlt" ? LinearSolverKind::LDLT : LinearSolverKind::ConjugateGradient;
        sc.cloth.implicit.cgTolerance = imp->number("cg_tolerance", 1e-10, kCgTolerance);
        sc.cloth.implicit.cgMaxIterations =
            static_cast<int>(imp->integer("cg_max_iterations", 500, 1, 100000));
        imp->finish();
    }
    o.finish();
    if (sc.duration / sc.timeStep > static_cast<double>(kMaxSceneSteps))
        o.fail(o.path(), "duration / time_step = " + JsonObject::fmt(sc.duration / sc.timeStep) +
                             " steps exceeds the limit of " + std::to_string(kMaxSceneSteps));
    if (sc.stepCount() == 0) o.failKey("duration", "is shorter than one time_step");
}

void parseStrainLimit(JsonObject o, SceneDesc& sc) {
    o.keys({"method", "max_strain", "max_rounds", "tolerance", "tolerance_step", "warm_start",
            "long_range_attachments", "long_range_slack"});
    LimiterSettings& l = sc.cloth.limiter;
    const std::string method =
        o.choice("method", "stress_ordered", {"stress_ordered", "provot", "none"});
    l.kind = limiterFromString(method);
    l.maxStrain = o.number("max_strain", l.maxStrain, kMaxStrain);
    l.maxRounds = static_cast<int>(o.integer("max_rounds", l.maxRounds, 1, 100000));
    l.tolerance = o.number("tolerance", l.tolerance, kStrainTolerance);
    l.toleranceStep = o.number("tolerance_step", l.toleranceStep, kToleranceStep);
    l.warmStart = o.number("warm_start", l.warmStart, kWarmStart);
    l.longRangeAttachments = o.boolean("long_range_attachments", l.longRangeAttachments);
    l.longRangeSlack = o.number("long_range_slack", l.longRangeSlack, kLongRangeSlack);
    o.finish();
}

void parsePins(JsonObject& parent, SceneDesc& sc) {
    const Json& arr = parent.array("pins", 100000);
    for (std::size_t i = 0; i < arr.size(); ++i) {
        JsonObject o(arr[i], parent.pathOf("pins") + "[" + std::to_string(i) + "]",
                     parent.origin());
        o.keys({"indices", "grid", "box", "groups", "velocity", "start_time", "end_time"});
        PinDesc p;
        p.select = parseSelector(o, sc.sheet.has_value());
        p.velocity = o.vec3("velocity", Vec3::Zero(), kVelocity);
        p.startTime = o.number("start_time", 0.0, kTime);
        p.endTime = o.number("end_time", 1e300, kTime);
        if (p.endTime < p.startTime) o.failKey("end_time", "must not be before start_time");
        o.finish();
        sc.pins.push_back(std::move(p));
    }
}

void parseAttachments(JsonObject& parent, SceneDesc& sc) {
    const Json& arr = parent.array("attachments", 100000);
    for (std::size_t i = 0; i < arr.size(); ++i) {
        JsonObject o(arr[i], parent.pathOf("attachments") + "[" + std::to_string(i) + "]",
                     parent.origin());
        o.keys({"body", "indices", "grid", "box", "groups"});
        AttachmentDesc a;
        a.body = o.requireString("body");
        a.select = parseSelector(o, sc.sheet.has_value());
        o.finish();
        sc.attachments.push_back(std::move(a));
    }
}

ShapeDesc parseShape(JsonObject o, const std::filesystem::path& baseDir, double unitsPerMetre) {
    o.keys({"type", "half_extents", "radius", "height", "normal", "offset", "mesh"});
    ShapeDesc s;
    if (!o.has("type")) o.failKey("type", "required field is missing");
    const std::string type = o.choice("type", "", {"box", "sphere", "capsule", "plane", "mesh"});
    if (type == "box") {
        s.kind = ShapeKind::Box;
        s.halfExtents = o.requireVec3("half_extents", kSize);
    } else if (type == "sphere") {
        s.kind = ShapeKind::Sphere;
        s.radius = o.requireNumber("radius", kSize);
    } else if (type == "capsule") {
        s.kind = ShapeKind::Capsule;
        s.radius = o.requireNumber("radius", kSize);
        s.height = o.requireNumber("height", kSizeOrZero);
    } else if (type == "plane") {
        s.kind = ShapeKind::Plane;
        s.normal = o.vec3("normal", Vec3::UnitY(), kDirection);
        if (s.normal.norm() < 1e-12) o.failKey("normal", "must not be zero");
        s.normal.normalize();
        s.offset = o.number("offset", 0.0, kCoordinate);
    } else {
        s.kind = ShapeKind::Mesh;
        JsonObject m = o.object("mesh");
        s.mesh = parseMeshDesc(std::move(m), baseDir, unitsPerMetre);
    }
    o.finish();
    return s;
}

void parseRigidBodies(JsonObject& parent, SceneDesc& sc, const std::filesystem::path& baseDir) {
    const Json& arr = parent.array("rigid_bodies", kMaxRigidBodies);
    for (std::size_t i = 0; i < arr.size(); ++i) {
        JsonObject o(arr[i], parent.pathOf("rigid_bodies") + "[" + std::to_string(i) + "]",
                     parent.origin());
        o.keys({"name", "shape", "motion", "position", "rotation_deg", "mass", "linear_velocity",
                "angular_velocity", "friction", "restitution", "launch_time", "keyframes",
                "color"});
        RigidBodyDesc b;
        b.path = o.path();
        b.name = o.string("name", "body" + std::to_string(i));
        for (const auto& other : sc.rigidBodies)
            if (other.name == b.name)
                o.failKey("name", "\"" + b.name + "\" is used by " + other.path + " already");
        b.shape = parseShape(o.object("shape"), baseDir, sc.unitsPerMetre);
        const std::string motion = o.choice("motion", "static", {"static", "kinematic", "dynamic"});
        b.motion = motion == "dynamic"     ? MotionKind::Dynamic
                   : motion == "kinematic" ? MotionKind::Kinematic
                                           : MotionKind::Static;
        b.position = o.vec3("position", Vec3::Zero(), kCoordinate);
        b.rotationDeg = o.vec3("rotation_deg", Vec3::Zero(), kAngle);
        b.mass = o.number("mass", 1.0, kBodyMass);
        if (o.has("mass") && b.motion != MotionKind::Dynamic)
            o.failKey("mass", "only dynamic bodies have a mass");
        b.linearVelocity = o.vec3("linear_velocity", Vec3::Zero(), kVelocity);
        b.angularVelocity = o.vec3("angular_velocity", Vec3::Zero(), kAngularVelocity);
        if ((o.has("linear_velocity") || o.has("angular_velocity")) &&
            b.motion != MotionKind::Dynamic)
            o.failKey("linear_velocity", "only dynamic bodies start with a velocity (kinematic "
                                         "bodies follow keyframes)");
        b.friction = o.number("friction", 0.5, kCoefficient);
        b.restitution = o.number("restitution", 0.0, kUnitInterval);
        b.launchTime = o.number("launch_time", 0.0, kTime);
        if (o.has("launch_time") && b.motion != MotionKind::Dynamic)
            o.failKey("launch_time", "only dynamic bodies are launched");
        const Json& keys = o.array("keyframes", 100000);
        if (!keys.empty() && b.motion != MotionKind::Kinematic)
            o.failKey("keyframes", "only kinematic bodies follow keyframes");
        for (std::size_t k = 0; k < keys.size(); ++k) {
            JsonObject ko(keys[k], o.pathOf("keyframes") + "[" + std::to_string(k) + "]",
                          o.origin());
            ko.keys({"time", "position", "rotation_deg"});
            KeyframeDesc kf;
            kf.time = ko.requireNumber("time", kTime);
            kf.position = ko.requireVec3("position", kCoordinate);
            kf.rotationDeg = ko.vec3("rotation_deg", Vec3::Zero(), kAngle);
            if (!b.keyframes.empty() && !(kf.time > b.keyframes.back().time))
                ko.failKey("time", "keyframe times must increase");
            ko.finish();
            b.keyframes.push_back(kf);
        }
        if (b.shape.kind == ShapeKind::Plane && b.motion != MotionKind::Static)
            o.failKey("motion", "planes are static");
        if (b.shape.kind == ShapeKind::Mesh && b.motion == MotionKind::Dynamic)
            o.failKey("motion", "triangle meshes are static or kinematic, not dynamic");
        b.color = o.color("color", b.color);
        o.finish();
        sc.rigidBodies.push_back(std::move(b));
    }
}

void parseCamera(JsonObject o, CameraDesc& c) {
    o.keys({"position", "target", "up", "fov_deg", "width", "height"});
    c.position = o.vec3("position", c.position, kCoordinate);
    c.target = o.vec3("target", c.target, kCoordinate);
    c.up = o.vec3("up", c.up, kDirection);
    if ((c.position - c.target).norm() < 1e-12) o.failKey("target", "must differ from position");
    if (c.up.norm() < 1e-12) o.failKey("up", "must not be zero");
    if (c.up.normalized().cross((c.target - c.position).normalized()).norm() < 1e-6)
        o.failKey("up", "must not be parallel to the viewing direction");
    c.fovDeg = o.number("fov_deg", c.fovDeg, kFov);
    c.width = static_cast<int>(o.integer("width", c.width, 16, kMaxImageSide));
    c.height = static_cast<int>(o.integer("height", c.height, 16, kMaxImageSide));
    o.finish();
}

void parseOutput(JsonObject o, OutputDesc& out) {
    o.keys({"fps", "png", "obj", "csv", "video", "background"});
    out.fps = o.number("fps", out.fps, kFps);
    out.png = o.boolean("png", out.png);
    out.obj = o.boolean("obj", out.obj);
    out.csv = o.boolean("csv", out.csv);
    out.video = o.boolean("video", out.video);
    out.background = o.color("background", out.background);
    o.finish();
}

} // namespace

SceneDesc parseScene(const std::string& text, const std::string& origin,
                     const std::filesystem::path& baseDir) {
    Json root;
    try {
        root = detail::parseJson(text, origin);
    } catch (const Json::parse_error& e) {
        // nlohmann's message carries the line and column.
        throw SceneError(origin + ": not valid JSON: " + e.what());
    } catch (const Json::exception& e) {
        // For example a number too large for a double ("1e999").
        throw SceneError(origin + ": not usable JSON: " + e.what());
    }
    JsonObject top(root, "", origin);
    top.keys({"name", "description", "units_per_metre", "cloth", "simulation", "strain_limit",
              "pins", "attachments", "wind", "rigid_bodies", "collision", "camera", "output"});
    SceneDesc sc;
    sc.name = top.string("name", "");
    sc.description = top.string("description", "");
    // The defaults in the scene's length unit (ClothSettings::inUnits); every value the file
    // gives is in that unit.
    sc.unitsPerMetre = top.number("units_per_metre", 1.0, kUnitsPerMetre);
    sc.cloth = ClothSettings::inUnits(sc.unitsPerMetre);
    sc.camera.position *= sc.unitsPerMetre; // 10 m away, in the scene's unit
    // The defaults are ClothSettings' (stress-ordered limiting at 10 %, ...); the Simulation
    // sub-steps itself (simulation.substeps: "auto", the default, or a count), so the cloth's
    // own automatic sub-steps stay off.
    sc.cloth.substeps.automatic = false;
    parseCloth(top.object("cloth"), sc, baseDir);
    if (auto s = top.optObject("simulation")) parseSimulation(std::move(*s), sc);
    if (auto s = top.optObject("strain_limit")) parseStrainLimit(std::move(*s), sc);
    parsePins(top, sc);
    parseRigidBodies(top, sc, baseDir);
    parseAttachments(top, sc);
    for (const auto& a : sc.attachments) {
        bool found = false;
        for (const auto& b : sc.rigidBodies)
            found = found || b.name == a.body;
        if (!found)
            throw SceneError(origin + ": " + a.select.path + ".body: no rigid body named \"" +
                             a.body + "\"");
    }
    if (auto w = top.optObject("wind")) {
        w->keys({"velocity", "gust_amplitude", "gust_frequency"});
        WindDesc wd;
        wd.velocity = w->vec3("velocity", Vec3::Zero(), kVelocity);
        wd.gustAmplitude = w->vec3("gust_amplitude", Vec3::Zero(), kVelocity);
        wd.gustFrequency = w->number("gust_frequency", 0.0, kFrequency);
        w->finish();
        if (!(sc.cloth.aero.airDensity > 0.0)) {
            // Air's density in the scene's units: 1.2 kg/m^3 is 1.2e-6 kg per cubic
            // centimetre (review 16: "1.2" copied into a centimetre scene was a million airs).
            const double u = sc.unitsPerMetre;
            std::ostringstream air;
            air << "wind acts through the air: add \"air\": {} to cloth (air's density, "
                << 1.2 / (u * u * u) << " kg per cubic ";
            if (u == 1.0)
                air << "metre";
            else
                air << "scene unit at units_per_metre " << u;
            air << "), or set cloth.air.density > 0 in kg per cubic scene unit";
            top.fail("wind", air.str());
        }
        sc.wind = wd;
    }
    if (auto c = top.optObject("collision")) {
        c->keys({"thickness", "friction_scale", "penalty_force", "continuous", "triangle_contacts",
                 "box_edges", "substeps", "self_collision", "self_thickness"});
        CollisionDesc cd;
        cd.thickness = c->optNumber("thickness", kSize);
        cd.frictionScale = c->number("friction_scale", 1.0, kCoefficient);
        cd.penaltyForce = c->optNumber("penalty_force", kPenaltyForce);
        cd.continuous = c->boolean("continuous", true);
        cd.triangleContacts = c->boolean("triangle_contacts", false);
        cd.boxEdges = c->boolean("box_edges", true); // as ContactSettings::boxEdges
        cd.substeps = static_cast<int>(c->integer("substeps", 1, 1, 1000));
        if (c->has("substeps")) {
            const auto sim = root.find("simulation");
            if (sim != root.end() && sim->is_object() && sim->contains("substeps"))
                c->failKey("substeps", "give the sub-steps once, as simulation.substeps "
                                       "(collision.substeps is its older name)");
            sc.substeps = cd.substeps;
            sc.autoSubsteps = false;
        }
        cd.selfCollision = c->boolean("self_collision", false);
        cd.selfThickness = c->optNumber("self_thickness", kSize);
        c->finish();
        if (sc.rigidBodies.empty() && !cd.selfCollision)
            top.fail("collision",
                     "there are no rigid_bodies to collide with (and self_collision is off)");
        sc.collision = cd;
    }
    if (auto c = top.optObject("camera")) parseCamera(std::move(*c), sc.camera);
    if (auto o = top.optObject("output")) parseOutput(std::move(*o), sc.output);
    top.finish();
    if (sc.output.fps * sc.duration > static_cast<double>(kMaxSceneFrames))
        throw SceneError(origin + ": output.fps: fps x duration = " +
                         JsonObject::fmt(sc.output.fps * sc.duration) +
                         " frames exceeds the limit of " + std::to_string(kMaxSceneFrames));
    return sc;
}

SceneDesc loadScene(const std::filesystem::path& file) {
    std::error_code ec;
    if (!std::filesystem::exists(file, ec))
        throw SceneError(file.string() + ": scene file not found");
    if (std::filesystem::is_directory(file, ec))
        throw SceneError(file.string() + ": is a folder, not a scene file");
    const auto size = std::filesystem::file_size(file, ec);
    if (ec) throw SceneError(file.string() + ": cannot read: " + ec.message());
    if (size > 64u * 1024u * 1024u)
        throw SceneError(file.string() + ": scene file larger than 64 MiB");
    std::ifstream in(file, std::ios::binary);
    if (!in) throw SceneError(file.string() + ": cannot open for reading");
    std::ostringstream ss;
    ss << in.rdbuf();
    SceneDesc sc = parseScene(ss.str(), file.string(), file.parent_path());
    sc.sourceFile = file;
    if (sc.name.empty()) sc.name = file.stem().string();
    return sc;
}

} // namespace drape::samples
