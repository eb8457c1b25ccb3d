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
using detail::Range;

std::size_t SceneDesc::stepCount() const {
    return static_cast<std::size_t>(std::llround(duration / timeStep));
}

namespace {

constexpr std::size_t kMaxListEntries = 1u << 20;

MeshDesc parseMeshDesc(JsonObject o, const std::filesystem::path& baseDir) {
    MeshDesc m;
    const std::string file = o.requireString("file");
    if (file.empty()) o.failKey("file", "must not be empty");
    m.file = std::filesystem::path(file);
    if (m.file.is_relative()) m.file = baseDir / m.file;
    if (const Json* s = o.find("scale")) {
        if (s->is_number()) {
            const double k = o.toNumber(*s, o.pathOf("scale"), Range::Positive);
            m.scale = Vec3::Constant(k);
        } else {
            m.scale = o.toVec3(*s, o.pathOf("scale"));
            for (int i = 0; i < 3; ++i)
                if (!(m.scale[i] > 0.0))
                    o.fail(o.pathOf("scale") + "[" + std::to_string(i) + "]", "must be > 0");
        }
    }
    m.rotationDeg = o.vec3("rotation_deg", m.rotationDeg);
    m.translation = o.vec3("translation", m.translation);
    m.weldTolerance = o.number("weld_tolerance", m.weldTolerance);
    o.finish();
    return m;
}

ParticleSelector parseSelector(JsonObject& o, bool isSheet) {
    ParticleSelector s;
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
        const Vec3 lo = box->requireVec3("min");
        const Vec3 hi = box->requireVec3("max");
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
    const bool hasSheet = o.has("sheet");
    const bool hasMesh = o.has("mesh");
    if (hasSheet == hasMesh)
        o.fail(o.path(),
               "give exactly one of cloth.sheet (a generated sheet) or cloth.mesh (a file)");
    if (hasSheet) {
        JsonObject s = o.object("sheet");
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
        d.spec.spacing = s.requireNumber("spacing", Range::Positive);
        d.spec.origin = s.vec3("origin", Vec3::Zero());
        d.spec.uAxis = s.vec3("u_axis", Vec3::UnitX());
        d.spec.vAxis = s.vec3("v_axis", -Vec3::UnitY());
        if (d.spec.uAxis.norm() < 1e-12) s.failKey("u_axis", "must not be zero");
        if (d.spec.vAxis.norm() < 1e-12) s.failKey("v_axis", "must not be zero");
        if (d.spec.uAxis.normalized().cross(d.spec.vAxis.normalized()).norm() < 1e-6)
            s.failKey("v_axis", "must not be parallel to u_axis");
        s.finish();
        sc.sheet = d;
    } else {
        sc.mesh = parseMeshDesc(o.object("mesh"), baseDir);
    }

    ClothSettings& c = sc.cloth;
    c.particleMass = o.number("particle_mass", 0.0, Range::Positive);
    c.totalMass = o.number("total_mass", 0.0, Range::Positive);
    if (o.has("particle_mass") && o.has("total_mass"))
        o.failKey("total_mass", "give particle_mass or total_mass, not both");
    const std::string lump = o.choice("mass_lumping", "uniform", {"uniform", "area"});
    c.lumping = lump == "area" ? MassLumping::AreaLumped : MassLumping::Uniform;
    c.springStiffness = o.number("stiffness", 0.0, Range::Positive);
    if (auto m = o.optObject("material")) {
        c.material.youngsModulus = m->number("youngs_modulus", 0.0, Range::Positive);
        c.material.thickness = m->number("thickness", 0.0, Range::Positive);
        c.material.density = m->number("density", 0.0, Range::Positive);
        m->finish();
    }
    const bool massGiven = c.particleMass > 0.0 || c.totalMass > 0.0 ||
                           (c.material.density > 0.0 && c.material.thickness > 0.0);
    if (!massGiven)
        o.fail(o.path(), "no mass: give particle_mass, total_mass, or material.density and "
                         "material.thickness");
    const bool stiffnessGiven =
        c.springStiffness > 0.0 || (c.material.youngsModulus > 0.0 && c.material.thickness > 0.0);
    if (!stiffnessGiven)
        o.fail(o.path(), "no stiffness: give stiffness, or material.youngs_modulus and "
                         "material.thickness");
    c.damping = o.number("damping", 0.0, Range::NonNegative);
    c.springDamping = o.number("spring_damping", 0.0, Range::NonNegative);
    if (auto a = o.optObject("air")) {
        c.aero.airDensity = a->number("density", 1.2, Range::NonNegative);
        c.aero.dragCoefficient = a->number("drag_coefficient", 1.0, Range::NonNegative);
        c.aero.liftCoefficient = a->number("lift_coefficient", 0.0, Range::NonNegative);
        a->finish();
    }
    sc.frontColor = o.color("front_color", sc.frontColor);
    sc.backColor = o.color("back_color", sc.backColor);
    o.finish();
}

void parseSimulation(JsonObject o, SceneDesc& sc) {
    const std::string integ = o.choice(
        "integrator", "velocity_verlet",
        {"velocity_verlet", "explicit_euler", "symplectic_euler", "rk4", "implicit_euler"});
    sc.cloth.integrator = integratorFromString(integ);
    sc.timeStep = o.number("time_step", sc.timeStep, Range::Positive);
    sc.duration = o.number("duration", sc.duration, Range::Positive);
    sc.cloth.gravity = o.vec3("gravity", Vec3(0.0, -9.81, 0.0));
    sc.cloth.rejectUnstableTimeStep = o.boolean("reject_unstable_time_step", true);
    if (auto imp = o.optObject("implicit")) {
        const std::string solver = imp->choice("solver", "cg", {"cg", "ldlt"});
        sc.cloth.implicit.solver =
            solver == "ldlt" ? LinearSolverKind::LDLT : LinearSolverKind::ConjugateGradient;
        sc.cloth.implicit.cgTolerance = imp->number("cg_tolerance", 1e-10, Range::Positive);
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
    LimiterSettings& l = sc.cloth.limiter;
    const std::string method =
        o.choice("method", "stress_ordered", {"stress_ordered", "provot", "none"});
    l.kind = limiterFromString(method);
    l.maxStrain = o.number("max_strain", 0.10, Range::Positive);
    l.maxRounds = static_cast<int>(o.integer("max_rounds", l.maxRounds, 1, 100000));
    l.tolerance = o.number("tolerance", l.tolerance, Range::NonNegative);
    l.warmStart = o.number("warm_start", l.warmStart, Range::NonNegative);
    if (l.warmStart >= 1.0) o.fail(o.pathOf("warm_start"), "must be in [0, 1)");
    l.longRangeAttachments = o.boolean("long_range_attachments", l.longRangeAttachments);
    l.longRangeSlack = o.number("long_range_slack", l.longRangeSlack, Range::Positive);
    if (l.longRangeSlack < 1.0) o.fail(o.pathOf("long_range_slack"), "must be >= 1");
    o.finish();
}

void parsePins(JsonObject& parent, SceneDesc& sc) {
    const Json& arr = parent.array("pins", 100000);
    for (std::size_t i = 0; i < arr.size(); ++i) {
        JsonObject o(arr[i], parent.pathOf("pins") + "[" + std::to_string(i) + "]",
                     parent.origin());
        PinDesc p;
        p.select = parseSelector(o, sc.sheet.has_value());
        p.velocity = o.vec3("velocity", Vec3::Zero());
        p.startTime = o.number("start_time", 0.0, Range::NonNegative);
        p.endTime = o.number("end_time", 1e300, Range::NonNegative);
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
        AttachmentDesc a;
        a.body = o.requireString("body");
        a.select = parseSelector(o, sc.sheet.has_value());
        o.finish();
        sc.attachments.push_back(std::move(a));
    }
}

ShapeDesc parseShape(JsonObject o, const std::filesystem::path& baseDir) {
    ShapeDesc s;
    if (!o.has("type")) o.failKey("type", "required field is missing");
    const std::string type = o.choice("type", "", {"box", "sphere", "capsule", "plane", "mesh"});
    if (type == "box") {
        s.kind = ShapeKind::Box;
        s.halfExtents = o.requireVec3("half_extents");
        for (int i = 0; i < 3; ++i)
            if (!(s.halfExtents[i] > 0.0))
                o.fail(o.pathOf("half_extents") + "[" + std::to_string(i) + "]", "must be > 0");
    } else if (type == "sphere") {
        s.kind = ShapeKind::Sphere;
        s.radius = o.requireNumber("radius", Range::Positive);
    } else if (type == "capsule") {
        s.kind = ShapeKind::Capsule;
        s.radius = o.requireNumber("radius", Range::Positive);
        s.height = o.requireNumber("height", Range::NonNegative);
    } else if (type == "plane") {
        s.kind = ShapeKind::Plane;
        s.normal = o.vec3("normal", Vec3::UnitY());
        if (s.normal.norm() < 1e-12) o.failKey("normal", "must not be zero");
        s.normal.normalize();
        s.offset = o.number("offset", 0.0);
    } else {
        s.kind = ShapeKind::Mesh;
        JsonObject m = o.object("mesh");
        s.mesh = parseMeshDesc(std::move(m), baseDir);
    }
    o.finish();
    return s;
}

void parseRigidBodies(JsonObject& parent, SceneDesc& sc, const std::filesystem::path& baseDir) {
    const Json& arr = parent.array("rigid_bodies", kMaxRigidBodies);
    for (std::size_t i = 0; i < arr.size(); ++i) {
        JsonObject o(arr[i], parent.pathOf("rigid_bodies") + "[" + std::to_string(i) + "]",
                     parent.origin());
        RigidBodyDesc b;
        b.path = o.path();
        b.name = o.string("name", "body" + std::to_string(i));
        for (const auto& other : sc.rigidBodies)
            if (other.name == b.name)
                o.failKey("name", "\"" + b.name + "\" is used by " + other.path + " already");
        b.shape = parseShape(o.object("shape"), baseDir);
        const std::string motion = o.choice("motion", "static", {"static", "kinematic", "dynamic"});
        b.motion = motion == "dynamic"     ? MotionKind::Dynamic
                   : motion == "kinematic" ? MotionKind::Kinematic
                                           : MotionKind::Static;
        b.position = o.vec3("position", Vec3::Zero());
        b.rotationDeg = o.vec3("rotation_deg", Vec3::Zero());
        b.mass = o.number("mass", 1.0, Range::Positive);
        if (o.has("mass") && b.motion != MotionKind::Dynamic)
            o.failKey("mass", "only dynamic bodies have a mass");
        b.linearVelocity = o.vec3("linear_velocity", Vec3::Zero());
        b.angularVelocity = o.vec3("angular_velocity", Vec3::Zero());
        if ((o.has("linear_velocity") || o.has("angular_velocity")) &&
            b.motion != MotionKind::Dynamic)
            o.failKey("linear_velocity", "only dynamic bodies start with a velocity (kinematic "
                                         "bodies follow keyframes)");
        b.friction = o.number("friction", 0.5, Range::NonNegative);
        b.restitution = o.number("restitution", 0.0, Range::UnitInterval);
        b.launchTime = o.number("launch_time", 0.0, Range::NonNegative);
        if (o.has("launch_time") && b.motion != MotionKind::Dynamic)
            o.failKey("launch_time", "only dynamic bodies are launched");
        const Json& keys = o.array("keyframes", 100000);
        if (!keys.empty() && b.motion != MotionKind::Kinematic)
            o.failKey("keyframes", "only kinematic bodies follow keyframes");
        for (std::size_t k = 0; k < keys.size(); ++k) {
            JsonObject ko(keys[k], o.pathOf("keyframes") + "[" + std::to_string(k) + "]",
                          o.origin());
            KeyframeDesc kf;
            kf.time = ko.requireNumber("time", Range::NonNegative);
            kf.position = ko.requireVec3("position");
            kf.rotationDeg = ko.vec3("rotation_deg", Vec3::Zero());
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
    c.position = o.vec3("position", c.position);
    c.target = o.vec3("target", c.target);
    c.up = o.vec3("up", c.up);
    if ((c.position - c.target).norm() < 1e-12) o.failKey("target", "must differ from position");
    if (c.up.norm() < 1e-12) o.failKey("up", "must not be zero");
    if (c.up.normalized().cross((c.target - c.position).normalized()).norm() < 1e-6)
        o.failKey("up", "must not be parallel to the viewing direction");
    c.fovDeg = o.number("fov_deg", c.fovDeg, Range::Positive);
    if (c.fovDeg >= 179.0) o.failKey("fov_deg", "must be below 179 degrees");
    c.width = static_cast<int>(o.integer("width", c.width, 16, kMaxImageSide));
    c.height = static_cast<int>(o.integer("height", c.height, 16, kMaxImageSide));
    o.finish();
}

void parseOutput(JsonObject o, OutputDesc& out) {
    out.fps = o.number("fps", out.fps, Range::Positive);
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
        root = Json::parse(text);
    } catch (const Json::parse_error& e) {
        // nlohmann's message carries the line and column.
        throw SceneError(origin + ": not valid JSON: " + e.what());
    } catch (const Json::exception& e) {
        // For example a number too large for a double ("1e999").
        throw SceneError(origin + ": not usable JSON: " + e.what());
    }
    JsonObject top(root, "", origin);
    SceneDesc sc;
    sc.name = top.string("name", "");
    sc.description = top.string("description", "");
    sc.cloth.limiter.kind = LimiterKind::None; // a scene asks for strain limiting explicitly
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
        WindDesc wd;
        wd.velocity = w->vec3("velocity", Vec3::Zero());
        wd.gustAmplitude = w->vec3("gust_amplitude", Vec3::Zero());
        wd.gustFrequency = w->number("gust_frequency", 0.0, Range::NonNegative);
        w->finish();
        if (!(sc.cloth.aero.airDensity > 0.0))
            top.fail("wind", "wind acts through the air: set cloth.air.density > 0 (1.2 for air)");
        sc.wind = wd;
    }
    if (auto c = top.optObject("collision")) {
        CollisionDesc cd;
        cd.thickness = c->number("thickness", -1.0);
        if (c->has("thickness") && !(cd.thickness > 0.0)) c->failKey("thickness", "must be > 0");
        cd.frictionScale = c->number("friction_scale", 1.0, Range::NonNegative);
        cd.penaltyForce = c->number("penalty_force", -1.0);
        if (c->has("penalty_force") && cd.penaltyForce < 0.0)
            c->failKey("penalty_force", "must be >= 0");
        cd.continuous = c->boolean("continuous", true);
        cd.substeps = static_cast<int>(c->integer("substeps", 1, 1, 1000));
        cd.selfCollision = c->boolean("self_collision", false);
        cd.selfThickness = c->number("self_thickness", -1.0);
        if (c->has("self_thickness") && !(cd.selfThickness > 0.0))
            c->failKey("self_thickness", "must be > 0");
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
