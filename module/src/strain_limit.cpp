// Strain limiters: the stress-ordered worklist (the default), Provot's sweeps and the literal
// one-sided walk (both for comparison), and the geodesic anchors of long-range attachments.
#include "drape/strain_limit.hpp"

#include <Eigen/Cholesky>

#include "drape/settings.hpp"

#include "parallel.hpp"
#include "restrict.hpp"
#include "simd.hpp"
#include "spring.hpp"
#include "spring_layout.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <numeric>
#include <queue>
#include <utility>

namespace drape {

namespace {
/// (l / L0)^2 of m consecutive family slots (0 for a hole): a and b are the coordinate runs of
/// the two ends. The arrays never overlap (DRAPE_RESTRICT), so the loop vectorises.
DRAPE_WIDE_KERNEL
void slotRatios(std::size_t m, const double* DRAPE_RESTRICT ax, const double* DRAPE_RESTRICT ay,
                const double* DRAPE_RESTRICT az, const double* DRAPE_RESTRICT bx,
                const double* DRAPE_RESTRICT by, const double* DRAPE_RESTRICT bz,
                const double* DRAPE_RESTRICT inv2, double* DRAPE_RESTRICT out) {
    for (std::size_t j = 0; j < m; ++j) {
        const double dx = bx[j] - ax[j], dy = by[j] - ay[j], dz = bz[j] - az[j];
        out[j] = detail::squaredLengthRatio(dx, dy, dz, inv2[j]);
    }
}
} // namespace

namespace {
/// The largest of r[0 .. m) (0 for none; the ratios are >= 0): four running maxima, so that
/// the maxima do not wait for each other (two-lane maxima, Double2, which return the same value
/// as std::max for any order of the non-negative ratios).
double largestRatio(const double* r, std::size_t m) {
    using detail::Double2;
    std::size_t j = 0;
    Double2 w01 = Double2::zero(), w23 = Double2::zero();
    for (; j + 4 <= m; j += 4) {
        w01 = max(Double2::load(r + j), w01);
        w23 = max(Double2::load(r + j + 2), w23);
    }
    const Double2 both = max(w01, w23);
    double w = std::max(both.low(), both.high());
    for (; j < m; ++j)
        w = std::max(w, r[j]);
    return w;
}

/// The first j in [from, end) with r[j] > bound, or end: four slots per test (Double2; most
/// slots are within the band).
std::size_t nextAbove(const double* r, std::size_t from, std::size_t end, double bound) {
    using detail::Double2;
    std::size_t j = from;
    const Double2 b = Double2::splat(bound);
    for (; j + 4 <= end; j += 4) {
        if (anyGreater(Double2::load(r + j), b) || anyGreater(Double2::load(r + j + 2), b)) break;
    }
    for (; j < end; ++j)
        if (r[j] > bound) return j;
    return end;
}
} // namespace

CarrierMatrices carrierMatrices(double invMass, const Eigen::Matrix3d& invInertia,
                                const std::vector<Vec3>& levers,
                                const std::vector<double>& masses) {
    using Matrix6 = Eigen::Matrix<double, 6, 6>;
    Matrix6 W = Matrix6::Zero();
    W.topLeftCorner<3, 3>() = invMass * Eigen::Matrix3d::Identity();
    W.bottomRightCorner<3, 3>() = invInertia;
    Matrix6 A = Matrix6::Zero();
    for (std::size_t k = 0; k < levers.size() && k < masses.size(); ++k) {
        Eigen::Matrix3d r;
        r << 0.0, -levers[k].z(), levers[k].y(), levers[k].z(), 0.0, -levers[k].x(), -levers[k].y(),
            levers[k].x(), 0.0; // [r]x: r x v = [r]x v
        const double m = masses[k];
        A.topLeftCorner<3, 3>() += m * Eigen::Matrix3d::Identity();
        A.topRightCorner<3, 3>() -= m * r;
        A.bottomLeftCorner<3, 3>() += m * r;
        A.bottomRightCorner<3, 3>() -= m * r * r;
    }
    // 1 + A W has eigenvalues >= 1 (A and W are positive semi-definite): always invertible.
    CarrierMatrices out;
    out.share = (Matrix6::Identity() + A * W).inverse();
    out.mobility = W * out.share;
    out.mobility = 0.5 * (out.mobility + out.mobility.transpose()); // symmetric, to rounding
    return out;
}

namespace {
/// constrainToJoints with up to MaxRows rows on the stack (Eigen::Dynamic: any number).
template <int MaxRows> void constrainRows(CarrierMatrices& m, const JointRows& joints) {
    using Rows = Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor, MaxRows, 6>;
    using Square = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, MaxRows, MaxRows>;
    const auto k = Eigen::Index(joints.rows.size());
    Rows J(k, 6);
    for (Eigen::Index r = 0; r < k; ++r)
        J.row(r) = joints.rows[std::size_t(r)].transpose();
    const Rows JM = J * m.mobility; // k x 6 (M is symmetric: (M J^T)^T)
    Square K = JM * J.transpose();  // k x k, symmetric semi-definite
    if (joints.give.rows() == k && joints.give.cols() == k) K += joints.give;
    // Rows that repeat one another (two ball joints on one axis: six rows of rank five) make K
    // singular: K + eps I, eps 1e-10 of its mean diagonal, solves it as its pseudo-inverse
    // would (J M f has no part along K's null directions, beyond rounding).
    const double scale = K.trace() / double(k);
    if (!(scale > 0.0) || !std::isfinite(scale)) return; // the rows ask nothing of this body
    K.diagonal().array() += 1e-10 * scale;
    const Eigen::LDLT<Square> ldlt(K);
    if (ldlt.info() != Eigen::Success) return;
    const Rows KJM = ldlt.solve(JM); // K^+ J M, k x 6
    const Eigen::Matrix<double, 6, 6> JtKJM = J.transpose() * KJM;
    m.share -= m.share * JtKJM;
    m.mobility -= m.mobility * JtKJM;
    m.mobility = 0.5 * (m.mobility + m.mobility.transpose()); // symmetric, to rounding
}
} // namespace

void constrainToJoints(CarrierMatrices& m, const JointRows& joints) {
    if (joints.rows.empty()) return;
    if (joints.rows.size() <= 12) {
        constrainRows<12>(m, joints);
    } else {
        constrainRows<Eigen::Dynamic>(m, joints);
    }
}

double maxSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x) {
    if (topology.springCount() == 0) return -std::numeric_limits<double>::infinity();
    // The largest squared length ratio, one square root at the end: the family slots from
    // coordinate arrays (the limiter's scan kernel, four lanes where the CPU has them), then
    // the loose springs (every spring is in one or the other). The largest of the same ratios
    // in any order: the same value as one loop over the springs.
    const detail::SpringLayout& layout = topology.springLayout();
    const auto& springs = topology.springs();
    const auto& inv2 = layout.inverseSquaredRest;
    double worst2 = 0.0;
    if (!layout.families.empty()) {
        thread_local std::vector<double> soa, ratio2;
        detail::toCoordinateArrays(nullptr, x, soa);
        ratio2.resize(layout.slotSpring.size());
        const std::size_t n = x.size();
        const double* px = soa.data();
        const double* py = px + n;
        const double* pz = py + n;
        for (const detail::SpringFamily& fam : layout.families) {
            const std::size_t a = fam.first;
            slotRatios(fam.count, px + a, py + a, pz + a, px + a + fam.offset, py + a + fam.offset,
                       pz + a + fam.offset, layout.slotInverseSquaredRest.data() + fam.slot,
                       ratio2.data() + fam.slot);
        }
        worst2 = largestRatio(ratio2.data(), ratio2.size());
    }
    for (Index s : layout.looseSprings)
        worst2 = std::max(worst2,
                          detail::squaredLengthRatio(x[springs[s].b] - x[springs[s].a], inv2[s]));
    return std::sqrt(worst2) - 1.0;
}

double meanSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x) {
    double sum = 0.0;
    for (const Spring& s : topology.springs())
        sum += (x[s.b] - x[s.a]).norm() / s.restLength - 1.0;
    return topology.springCount() ? sum / static_cast<double>(topology.springCount()) : 0.0;
}

// --- geodesic anchors ------------------------------------------------------------------------

void setSlack(AnchorField& field, double slack) {
    const std::size_t n = field.anchor.size();
    field.restDistance.assign(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
        if (field.anchor[i] != kNoParticle)
            field.restDistance[i] = std::min(field.pathLength[i], slack * field.geodesic[i]);
    }
}

AnchorField geodesicAnchors(const ClothTopology& topology, const std::vector<Index>& anchors,
                            double slack) {
    const std::size_t n = topology.particleCount();
    const auto& X = topology.restPositions();
    const auto& off = topology.adjacencyOffsets();
    const auto& nbr = topology.adjacentParticles();
    const auto& adjSpring = topology.adjacentSprings();
    const auto& springs = topology.springs();
    auto rest = [&](std::size_t k) { return springs[adjSpring[k]].restLength; };
    constexpr double inf = std::numeric_limits<double>::infinity();
    std::vector<double> geo(n, inf), path(n, inf);
    std::vector<Index> src(n, kNoParticle);
    std::vector<unsigned char> done(n, 0);
    // Triangles around each particle, for the unfolding update.
    std::vector<Index> triOff(n + 1, 0), triOf;
    const auto& tris = topology.triangles();
    for (const Triangle& t : tris)
        for (Index v : t)
            ++triOff[v + 1];
    for (std::size_t i = 0; i < n; ++i)
        triOff[i + 1] += triOff[i];
    triOf.resize(triOff[n]);
    {
        std::vector<Index> fill(triOff.begin(), triOff.end() - 1);
        for (std::size_t t = 0; t < tris.size(); ++t)
            for (Index v : tris[t])
                triOf[fill[v]++] = static_cast<Index>(t);
    }
    using Item = std::pair<double, Index>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> front;
    for (Index a : anchors) {
        if (a >= n || geo[a] == 0.0) continue;
        geo[a] = path[a] = 0.0;
        src[a] = a;
        front.push({0.0, a});
    }
    auto offer = [&](Index c, double g, double p, Index s) {
        // Never below the straight rest distance to the anchor: a lower bound of any geodesic.
        g = std::max(g, (X[c] - X[s]).norm());
        if (g < geo[c]) {
            geo[c] = g;
            path[c] = p;
            src[c] = s;
            front.push({g, c});
        }
    };
    while (!front.empty()) {
        const auto [g, a] = front.top();
        front.pop();
        if (done[a] || g > geo[a]) continue;
        done[a] = 1;
        for (Index k = off[a]; k < off[a + 1]; ++k) {
            const Index c = nbr[k];
            if (!done[c]) offer(c, geo[a] + rest(k), path[a] + rest(k), src[a]);
        }
        // Across each triangle (a, b, c) with b already final and from the same anchor:
        // unfold a, b, c into the triangle's plane, a = (0, 0), b = (e, 0), c above the edge;
        // the virtual source S below the edge at distances geo[a], geo[b]; geo[c] = |c - S|
        // when the segment S-c crosses the edge a-b.
        for (Index k = triOff[a]; k < triOff[a + 1]; ++k) {
            const Triangle& t = tris[triOf[k]];
            Index other[2];
            int m = 0;
            for (Index v : t)
                if (v != a && m < 2) other[m++] = v;
            if (m < 2) continue;
            for (int j = 0; j < 2; ++j) {
                const Index b = other[j], c = other[1 - j];
                if (b == c || !done[b] || done[c] || src[b] != src[a]) continue;
                const Vec3 ab = X[b] - X[a], ac = X[c] - X[a];
                const double e = ab.norm();
                if (!(e > 0.0)) continue;
                const Vec3 u = ab / e;
                const double cx = ac.dot(u), cy = (ac - cx * u).norm();
                if (!(cy > 0.0)) continue;
                const double da = geo[a], db = geo[b];
                const double sx = (da * da - db * db + e * e) / (2.0 * e);
                const double sy2 = da * da - sx * sx;
                if (sy2 < 0.0) continue;
                const double sy = -std::sqrt(sy2);
                const double cross = sx + (cx - sx) * (-sy) / (cy - sy); // where S-c meets y = 0
                if (cross < 0.0 || cross > e) continue;
                const double gc = std::hypot(cx - sx, cy - sy);
                const double pc =
                    std::min(path[a] + (X[c] - X[a]).norm(), path[b] + (X[c] - X[b]).norm());
                offer(c, gc, pc, src[a]);
            }
        }
    }
    AnchorField field;
    field.anchor = src;
    field.pathLength.assign(n, 0.0);
    field.geodesic.assign(n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
        if (src[i] == kNoParticle) continue;
        field.pathLength[i] = path[i];
        field.geodesic[i] = geo[i];
    }
    setSlack(field, slack);
    return field;
}

// --- the worklist limiter -------------------------------------------------------------------

void StrainLimiter::sortWarmList() {
    if (!warmListValid_) { // after a restore or reset: every spring with a correction
        warmList_.clear();
        std::fill(inWarmList_.begin(), inWarmList_.end(), 0);
        std::fill(warmLeft_.begin(), warmLeft_.end(), 0.0);
        clearWarmBits();
        for (std::size_t si = 0; si < lambda_.size(); ++si) {
            if (lambda_[si] == 0.0) continue;
            warmList_.push_back(static_cast<std::uint32_t>(si));
            inWarmList_[si] = 1;
        }
        warmListValid_ = true;
        return;
    }
    // The springs the last step added come after the sorted ones it kept.
    const auto mid =
        warmList_.begin() + static_cast<std::ptrdiff_t>(std::min(warmSorted_, warmList_.size()));
    std::sort(mid, warmList_.end());
    std::inplace_merge(warmList_.begin(), mid, warmList_.end());
}

void StrainLimiter::clearMoved() {
    for (Index i : movedIndex_)
        moved_[i] = 0;
    movedIndex_.clear();
    movedFrom_.clear();
    for (Index i : heldIndex_) {
        pulled_[i] = 0;
        heldPull_[i].setZero();
    }
    heldIndex_.clear();
}

void StrainLimiter::firstMove(Index i, const std::vector<Vec3>& x) {
    moved_[i] = 1;
    movedIndex_.push_back(i);
    movedFrom_.push_back(x[i]);
}

double StrainLimiter::slidingWeight(Index i, double w, const Vec3& dir, const std::vector<Vec3>& x,
                                    double eps) const {
    const std::int32_t k = planes_->of[i];
    if (k < 0 || w == 0.0) return w;
    const Vec3& n = planes_->normal[std::size_t(k)];
    const double dn = dir.dot(n);
    if (dn >= 0.0) return w;                                              // away from the plane
    if (n.dot(x[i]) - planes_->offsetNow(std::size_t(k)) > eps) return w; // above it: free
    return w * std::max(0.0, 1.0 - dn * dn);
}

Vec3 StrainLimiter::keepAbove(Index i, const Vec3& dx, const std::vector<Vec3>& x) const {
    const std::int32_t k = planes_->of[i];
    if (k < 0) return dx;
    const std::size_t kk = std::size_t(k);
    const Vec3& n = planes_->normal[kk];
    double below = planes_->offsetNow(kk) - n.dot(x[i] + dx);
    if (!(below > 0.0)) return dx;
    if (planes_->mover[kk] >= 0) {
        // A particle its long-range attachment holds (taut from a pinned particle) is backed
        // by the pin: the body takes what the attachment leaves no room for.
        // Only where the plane pushes the body mostly through its centre of mass (its give
        // there at most twice its inverse mass): pushed off-centre by the whole pin's hold, a
        // light body (a bar struck near its end) spins up instead.
        const ContactPlanes::Mover& body = planes_->movers[std::size_t(planes_->mover[kk])];
        const bool pinned = anchorsHold_ && body.backed && planes_->give[kk] <= 2.0 * body.invMass;
        const double room =
            pinned ? anchorRoom(i, x[i] + dx, n, x) : std::numeric_limits<double>::infinity();
        below = planes_->giveWay(kk, below, (*planeInvMass_)[i], room, pinned ? body.lighten : 1.0);
    }
    Vec3& push = planes_->push[kk];
    push += below * n;
    if (const double most = planes_->pushLimit[kk]; push.squaredNorm() > most * most) {
        planes_->offset[kk] = -std::numeric_limits<double>::infinity(); // let go (pushLimit)
        ++planes_->letGo;
    }
    return dx + below * n;
}

namespace {
/// The particles that never move in the limiter (zero inverse mass: pinned, kinematic,
/// attached), in index order, into `out`.
void heldParticles(const std::vector<double>& invMass, std::vector<Index>& out) {
    out.clear();
    for (std::size_t i = 0; i < invMass.size(); ++i)
        if (invMass[i] == 0.0) out.push_back(static_cast<Index>(i));
}

/// Whether `list` (ascending, as heldParticles makes it) holds exactly the particles of zero
/// inverse mass: one count without branches (by blocks of `block` particles on the
/// executor's threads, each into its own entry of `counts`), then a look at the listed ones.
bool heldAre(const std::vector<double>& invMass, const std::vector<Index>& list, Executor* executor,
             std::size_t block, std::vector<std::size_t>& counts) {
    const std::size_t n = invMass.size(), blocks = (n + block - 1) / block;
    counts.resize(blocks);
    detail::forChunks(
        executor, blocks,
        [&](std::size_t b0, std::size_t b1) {
            for (std::size_t bl = b0; bl < b1; ++bl) {
                std::size_t held = 0;
                for (std::size_t i = bl * block, end = std::min(n, i + block); i < end; ++i)
                    held += invMass[i] == 0.0;
                counts[bl] = held;
            }
        },
        2);
    std::size_t held = 0;
    for (std::size_t c : counts)
        held += c;
    if (held != list.size()) return false;
    return std::all_of(list.begin(), list.end(),
                       [&](Index i) { return i < invMass.size() && invMass[i] == 0.0; });
}
} // namespace

void StrainLimiter::prepare(const ClothTopology& topology, const std::vector<double>& invMass,
                            const LimiterSettings& s) {
    const std::size_t n = topology.particleCount(), ns = topology.springCount();
    if (lambda_.size() != ns) {
        lambda_.assign(ns, 0.0);
        warmListValid_ = false;
    }
    inWarmList_.resize(ns, 0);
    queued_.resize(ns, 0);
    warmLeft_.resize(ns, 0.0);
    key_.resize(ns, 0.0);
    checkedAt_.resize(ns, 0u);
    candidates_.resize(topology.adjacentSprings().size() + 1);
    dirtyAt_.resize(n, 0u);
    moved_.resize(n, 0);
    pulled_.resize(n, 0);
    heldPull_.resize(n, Vec3::Zero());
    const double band = limiterBand(s);
    const double upper = 1.0 + s.maxStrain + band;
    const double lower = std::max(0.0, 1.0 + s.maxStrain - band);
    upper2_ = upper * upper;
    lower2_ = lower * lower;
    limit_ = 1.0 + s.maxStrain;
    anchorsHold_ = false;
    if (!s.longRangeAttachments) return;
    // The anchors are the particles that never move in the limiter.
    if (!anchorsValid_ || !heldAre(invMass, anchorList_, executor_, kScanSegment, blockHeld_)) {
        heldParticles(invMass, anchorList_);
        anchors_ = geodesicAnchors(topology, anchorList_, s.longRangeSlack);
        anchorsValid_ = true;
    } else if (anchorSlack_ != s.longRangeSlack) {
        setSlack(anchors_, s.longRangeSlack); // another dt (longRangeSlackAt): O(n), no search
    }
    anchorSlack_ = s.longRangeSlack;
    anchorsHold_ = !anchorList_.empty();
}

double StrainLimiter::anchorRoom(Index i, const Vec3& at, const Vec3& n,
                                 const std::vector<Vec3>& x) const {
    const Index a = anchors_.anchor[i];
    if (a == kNoParticle) return std::numeric_limits<double>::infinity();
    // The largest t >= 0 with |at + t n - x_a| <= r: t^2 + 2 t (y . n) + |y|^2 - r^2 <= 0.
    const Vec3 y = at - x[a];
    const double r = limit_ * anchors_.restDistance[i];
    const double yn = y.dot(n);
    const double disc = yn * yn - y.squaredNorm() + r * r;
    return disc > 0.0 ? std::max(0.0, std::sqrt(disc) - yn) : 0.0;
}

double StrainLimiter::check(std::size_t si, const ClothTopology& topology,
                            const std::vector<double>& invMass,
                            const std::vector<double>& stiffness, const std::vector<Vec3>& x,
                            StrainLimitStats& st) {
    if (queued_[si]) return 0.0;
    const Spring& sp = topology.springs()[si];
    ++st.work;
    const double ratio2 =
        (x[sp.b] - x[sp.a]).squaredNorm() * topology.springLayout().inverseSquaredRest[si];
    if (needs(si, ratio2) && linked(sp.a, sp.b, invMass[sp.a], invMass[sp.b]))
        queue(si, ratio2, sp.restLength, stiffness);
    return ratio2;
}

StrainLimitStats StrainLimiter::limit(const ClothTopology& topology,
                                      const std::vector<double>& invMass,
                                      const std::vector<double>& stiffness,
                                      const LimiterSettings& s, std::vector<Vec3>& x,
                                      ContactPlanes* planes) {
    StrainLimitStats st;
    prepare(topology, invMass, s);
    usePlanes(planes, invMass);
    const auto& springs = topology.springs();
    const std::size_t ns = springs.size();
    auto moveTo = [this, &x](Index i, const Vec3& dx) { move(i, dx, x); };
    // 1. Long-range attachments.
    if (s.longRangeAttachments && !anchorList_.empty()) {
        // (Local pointers: move() appends to vectors, which would make the compiler reload
        // every member's data pointer in every iteration.)
        const double f = limit_;
        const bool record = recordHeld_;
        const Index* anchor = anchors_.anchor.data();
        const double* restDistance = anchors_.restDistance.data();
        const double* w = invMass.data();
        std::size_t evaluated = 0;
        auto pullIn = [&](std::size_t i) {
            const Index a = anchor[i];
            const Vec3 d = x[i] - x[a];
            const double l2 = d.squaredNorm(), r = f * restDistance[i];
            if (l2 > r * r) {
                Vec3 dx = (r / std::sqrt(l2) - 1.0) * d;
                if (planes_) // a light body carrying the anchor comes along
                    if (const std::int32_t c = carriedEntry(a); c >= 0)
                        dx = shareWithCarrier(c, dx, w[i], x, moveTo);
                move(static_cast<Index>(i), abovePlanes(Index(i), dx, x), x);
                if (planes_) holdTriangles(Index(i), x, moveTo);
                if (record) pullHeld(a, -dx / w[i]);
            }
        };
        if (planes_) {
            // A move may move other particles (holdTriangles): one pass, in index order.
            for (std::size_t i = 0; i < x.size(); ++i) {
                if (anchor[i] == kNoParticle || w[i] == 0.0) continue;
                ++evaluated;
                pullIn(i);
            }
        } else {
            // A move moves its own particle only (an anchor never moves), so every particle
            // beyond its reach is known before the first move: they are listed without
            // branches (which particles sit at their reach follows no pattern), by blocks of
            // kScanSegment particles on any thread, each into its own part of the list, then
            // moved in index order, as one pass would (the same moves for any thread count).
            const std::size_t n = x.size();
            const std::size_t blocks = (n + kScanSegment - 1) / kScanSegment;
            beyondReach_.resize(n);
            blockBeyond_.resize(blocks);
            blockAnchored_.resize(blocks);
            const Vec3* xp = x.data();
            auto list = [&](std::size_t b0, std::size_t b1) {
                for (std::size_t bl = b0; bl < b1; ++bl) {
                    const std::size_t first = bl * kScanSegment,
                                      end = std::min(n, first + kScanSegment);
                    Index* beyond = beyondReach_.data() + first;
                    std::size_t count = 0, anchoredCount = 0;
                    for (std::size_t i = first; i < end; ++i) {
                        const Index a = anchor[i];
                        const bool anchored = (a != kNoParticle) & (w[i] != 0.0); // and free
                        const Vec3 d = xp[i] - xp[anchored ? a : Index(i)];
                        const double r = f * restDistance[i];
                        beyond[count] = static_cast<Index>(i);
                        count += anchored & (d.squaredNorm() > r * r);
                        anchoredCount += anchored;
                    }
                    blockBeyond_[bl] = count;
                    blockAnchored_[bl] = anchoredCount;
                }
            };
            detail::forChunks(executor_, blocks, list, 2);
            for (std::size_t bl = 0; bl < blocks; ++bl) {
                evaluated += blockAnchored_[bl];
                const Index* beyond = beyondReach_.data() + bl * kScanSegment;
                for (std::size_t k = 0; k < blockBeyond_[bl]; ++k)
                    pullIn(beyond[k]);
            }
        }
        st.work += evaluated;
    }
    // 2. Warm start: last step's corrections, scaled, along the springs as they are now;
    // never more than would shorten a spring to half its rest length (a correction so large
    // that the spring turned since must not flip it). warmLeft_ is what a let-out may undo.
    // Only the springs of warmList_ can have a correction; they are visited in index order
    // (the same order as a loop over all springs), and those left without one drop out.
    sortWarmList();
    std::size_t kept = 0, warmed = 0;
    {
        // Two passes: every correction is measured on the positions the warm start found
        // (its springs' lengths do not wait for each other's moves), then applied.
        // pull[k] is set exactly for the springs whose lambda stays nonzero, the only ones
        // the second pass reads it for.
        std::uint32_t* list = warmList_.data();
        double* lambda = lambda_.data();
        double* left = warmLeft_.data();
        std::uint32_t* checked = checkedAt_.data();
        unsigned char* listed = inWarmList_.data();
        const Spring* spring = springs.data();
        const double* w = invMass.data();
        const Vec3* xp = x.data();
        const double share = s.warmStart;
        const bool record = recordHeld_;
        warmMove_.resize(warmList_.size());
        Vec3* pull = warmMove_.data();
        for (std::size_t k = 0; k < warmList_.size(); ++k) {
            const std::uint32_t si = list[k];
            double lam = lambda[si];
            if (lam != 0.0) {
                ++warmed;
                const Spring& sp = spring[si];
                const double wsum = w[sp.a] + w[sp.b];
                const Vec3 d = xp[sp.b] - xp[sp.a];
                const double l = d.norm();
                lam = wsum > 0.0
                          ? std::min(lam * share, std::max(0.0, l - 0.5 * sp.restLength) / wsum)
                          : 0.0;
                if (lam != 0.0) pull[k] = (lam / l) * d;
            }
            lambda[si] = lam;
            left[si] = lam;
            checked[si] = withWarmBit(checked[si], lam);
        }
        for (std::size_t k = 0; k < warmList_.size(); ++k) {
            const std::uint32_t si = list[k];
            if (lambda[si] == 0.0) {
                listed[si] = 0;
                continue;
            }
            list[kept++] = si;
            const Spring& sp = spring[si];
            if (w[sp.a] > 0.0) {
                move(sp.a, abovePlanes(sp.a, w[sp.a] * pull[k], x), x);
                if (planes_) holdTriangles(sp.a, x, moveTo);
            } else if (record) {
                pullHeld(sp.a, pull[k]);
            }
            if (w[sp.b] > 0.0) {
                move(sp.b, abovePlanes(sp.b, -w[sp.b] * pull[k], x), x);
                if (planes_) holdTriangles(sp.b, x, moveTo);
            } else if (record) {
                pullHeld(sp.b, -pull[k]);
            }
        }
    }
    st.work += warmed;
    warmList_.resize(kept);
    warmSorted_ = kept;
    // 3. One scan of every spring: the families through coordinate arrays (springs beyond the
    // band), then the warm-started family springs below it, then the loose springs one by one.
    next_.clear();
    double worst2 = scanFamilies(topology, invMass, stiffness, x, st);
    const auto& slotOf = topology.springLayout().springSlot;
    for (std::uint32_t si : warmList_) {
        const std::size_t slot = slotOf[si];
        if (slot == detail::kNoSlot || queued_[si] || !(ratio2_[slot] < lower2_)) continue;
        const Spring& sp = springs[si];
        if (linked(sp.a, sp.b, invMass[sp.a], invMass[sp.b]))
            queue(si, ratio2_[slot], sp.restLength, stiffness);
    }
    for (Index si : topology.springLayout().looseSprings) {
        worst2 = std::max(worst2, check(si, topology, invMass, stiffness, x, st));
    }
    st.maxStrainBefore = ns ? std::sqrt(worst2) - 1.0 : 0.0;
    // 4. The waves.
    runWaves(topology, invMass, stiffness, s, x, st);
    planes_ = nullptr;
    finish(topology, x, st);
    return st;
}

double StrainLimiter::scanFamilies(const ClothTopology& topology,
                                   const std::vector<double>& invMass,
                                   const std::vector<double>& stiffness, const std::vector<Vec3>& x,
                                   StrainLimitStats& st) {
    const detail::SpringLayout& layout = topology.springLayout();
    const auto& families = layout.families;
    if (families.empty()) return 0.0;
    const std::size_t n = x.size();
    const auto& slotSpring = layout.slotSpring;
    const auto& inv2 = layout.slotInverseSquaredRest;
    ratio2_.resize(slotSpring.size());
    // Both passes split over threads by particle and by slot (each value written by one piece):
    // the same ratios for any thread count.
    detail::toCoordinateArrays(executor_, x, soa_);
    // The slots in segments: each measures its slots, their largest ratio and whether any is
    // beyond the band (four running maxima: one chain of maxima would make every slot wait for
    // the one before it). Segments run on any thread; the largest ratio is exact whatever the
    // order, and only segments with a spring beyond the band (the rare case) are read again,
    // in index order, to queue them.
    const std::size_t m = slotSpring.size();
    const std::size_t segments = (m + kScanSegment - 1) / kScanSegment;
    segmentWorst_.resize(segments);
    auto measure = [&](std::size_t s0, std::size_t s1) {
        const double* px = soa_.data();
        const double* py = px + n;
        const double* pz = py + n;
        double* r2 = ratio2_.data();
        for (std::size_t sg = s0; sg < s1; ++sg) {
            const std::size_t b = sg * kScanSegment, e = std::min(m, b + kScanSegment);
            for (const detail::SpringFamily& fam : families) {
                const std::size_t lo = std::max(b, fam.slot);
                const std::size_t hi = std::min(e, fam.slot + fam.count);
                if (lo >= hi) continue;
                const std::size_t a = fam.first + (lo - fam.slot); // the first end of slot lo
                slotRatios(hi - lo, px + a, py + a, pz + a, px + a + fam.offset,
                           py + a + fam.offset, pz + a + fam.offset, inv2.data() + lo, r2 + lo);
            }
            segmentWorst_[sg] = largestRatio(r2 + b, e - b);
        }
    };
    detail::forChunks(executor_, segments, measure, 2);
    st.work += topology.springCount() - layout.looseSprings.size();
    // Springs beyond the band. A hole has ratio 0. The warm-started springs below the band are
    // found by limit() from its list.
    const auto& springs = topology.springs();
    const double* r2 = ratio2_.data();
    const double upper2 = upper2_;
    double worst2 = 0.0;
    for (std::size_t sg = 0; sg < segments; ++sg) {
        worst2 = std::max(worst2, segmentWorst_[sg]);
        if (!(segmentWorst_[sg] > upper2)) continue;
        const std::size_t e = std::min(m, (sg + 1) * kScanSegment);
        for (std::size_t j = sg * kScanSegment; j < e;) {
            j = nextAbove(r2, j, e, upper2);
            if (j == e) break;
            const Index si = slotSpring[j];
            const Spring& sp = springs[si];
            if (linked(sp.a, sp.b, invMass[sp.a], invMass[sp.b]))
                queue(si, r2[j], sp.restLength, stiffness);
            ++j;
        }
    }
    return worst2;
}

StrainLimitStats StrainLimiter::relimit(const ClothTopology& topology,
                                        const std::vector<double>& invMass,
                                        const std::vector<double>& stiffness,
                                        const LimiterSettings& s, const std::vector<Index>& touched,
                                        std::vector<Vec3>& x, ContactPlanes* planes) {
    StrainLimitStats st;
    prepare(topology, invMass, s);
    usePlanes(planes, invMass);
    next_.clear();
    const auto& off = topology.adjacencyOffsets();
    const auto& spr = topology.adjacentSprings();
    for (Index i : touched) {
        if (i >= x.size()) continue;
        for (Index k = off[i]; k < off[i + 1]; ++k)
            check(spr[k], topology, invMass, stiffness, x, st);
    }
    runWaves(topology, invMass, stiffness, s, x, st);
    planes_ = nullptr;
    finish(topology, x, st);
    return st;
}

void StrainLimiter::finish(const ClothTopology& topology, const std::vector<Vec3>& x,
                           StrainLimitStats& st) const {
    if (st.capHit) {
        st.maxStrainAfter = maxSpringStrain(topology, x); // what the cap left: measured
    } else if (st.corrections > 0) {
        st.maxStrainAfter =
            std::sqrt(upper2_) - 1.0; // every spring passed a check after its last move
    } else {
        st.maxStrainAfter = st.maxStrainBefore;
    }
}

namespace {
/// The sort key of a queued spring: its tension, rounded to float, in the high half, mapped
/// to an unsigned integer that grows as the tension falls (the IEEE bits ordered as numbers,
/// then complemented); the spring's index in the low half. Ascending keys are the wave's
/// order: most stressed first, tensions equal to float precision (1e-7 relative) by index.
std::uint64_t waveKey(double tension, std::uint32_t spring) {
    const auto t = static_cast<float>(tension);
    std::uint32_t u = 0;
    std::memcpy(&u, &t, sizeof u);
    u = (u & 0x80000000u) != 0u ? ~u : (u | 0x80000000u); // grows with t
    return (std::uint64_t(~u) << 32) | spring;
}
} // namespace

template <bool kPlanes, bool kRecordHeld>
std::size_t StrainLimiter::correctWave(const std::vector<Spring>& springs,
                                       const std::vector<double>& invMass, std::vector<Vec3>& x,
                                       StrainLimitStats& st) {
    // (Local pointers: warmList_.push_back and firstMove write to members, which would make
    // the compiler reload every member's data pointer after them.)
    const Spring* spring = springs.data();
    const double* w = invMass.data();
    Vec3* xp = x.data();
    double* lambda = lambda_.data();
    double* left = warmLeft_.data();
    std::uint32_t* checked = checkedAt_.data();
    unsigned char* listed = inWarmList_.data();
    const unsigned char* moved = moved_.data();
    std::uint32_t* dirtyAt = dirtyAt_.data();
    Index* dirty = dirty_.data();
    const std::uint32_t stamp = stamp_;
    const double limit = limit_;
    std::size_t nd = 0, corrections = 0;
    // Moves particle i and lists it once for the checks after the wave (appended by adding 0
    // or 1 to the count: dirty_ has room for every particle).
    auto shift = [&](Index i, const Vec3& dx) {
        if (!moved[i]) firstMove(i, x);
        xp[i] += dx;
        dirty[nd] = i;
        nd += dirtyAt[i] != stamp;
        dirtyAt[i] = stamp;
    };
    for (const std::uint64_t item : order_) {
        const auto si = static_cast<std::uint32_t>(item); // the low half
        const Index a = spring[si].a, b = spring[si].b;
        const Vec3 d = xp[b] - xp[a];
        const double l = d.norm();
        const double wa = w[a], wb = w[b];
        if (!(l > 0.0)) continue;
        if (wa + wb == 0.0) {
            if constexpr (!kPlanes)
                continue;
            else if (!carriedApart(a, b))
                continue;
        }
        const double excess = l - limit * spring[si].restLength;
        // A contact plane the particle lies on takes the normal part of its move: it counts
        // with w (1 - (u . n)^2) (first order). Shortening moves a along +u.
        double wsum = wa + wb;
        // A held end a free body carries (ContactPlanes::Carried) moves with the body.
        // carriedAt[end]: that end's carried entry (end 0: a, 1: b) or -1, and its lever now.
        std::int32_t carriedAt[2] = {-1, -1};
        Vec3 carriedLever[2];
        if constexpr (kPlanes) {
            const Vec3 u = d / l;
            const double eps = 1e-6 * spring[si].restLength;
            const double sgn = excess > 0.0 ? 1.0 : -1.0;
            wsum = slidingWeight(a, wa, sgn * u, x, eps) + slidingWeight(b, wb, -sgn * u, x, eps);
            if (wa == 0.0) carriedAt[0] = carriedEntry(a);
            if (wb == 0.0) carriedAt[1] = carriedEntry(b);
            for (int end = 0; end < 2; ++end) {
                if (carriedAt[end] < 0) continue;
                const ContactPlanes::Carried& e = planes_->carried[std::size_t(carriedAt[end])];
                carriedLever[end] = planes_->carriedLever(e);
                wsum += planes_->movers[std::size_t(e.mover)].giveAlong(u, carriedLever[end]);
            }
            if (!(wsum > 0.0)) continue; // both ends held by their planes
            // One end pinned, the other on the plane of a body that does not give way (one
            // that does takes its share): a slide along the plane shortens a spring that meets
            // it at an angle theta from the normal only by a slide of about excess / sin(theta)
            // (weight w sin^2 theta). Near the normal that is a jump, not a correction, and the
            // plane pushes back what the jump put into it, again in every wave (a neighbour
            // attached across the plane, which no slide brings within the bound): the spring is
            // left as it is, the plane wins (the strain the step ends with counts it).
            if (((wa == 0.0 && carriedAt[0] < 0 && onStillPlane(b)) ||
                 (wb == 0.0 && carriedAt[1] < 0 && onStillPlane(a))) &&
                !(wsum > (wa + wb) * std::min(1.0, std::abs(excess) / l)))
                continue;
        }
        // Provot's rule: to exactly the limit, by inverse-mass shares. A pull adds to the
        // spring's lambda; a spring the warm start pulled in too far is let out to the limit,
        // by at most what the warm start applied (never a push).
        const double want = excess / wsum;
        const double dl = want >= 0.0 ? want : std::max(want, -left[si]);
        if (dl == 0.0) continue;
        lambda[si] += dl;
        if (!listed[si]) {
            listed[si] = 1;
            warmList_.push_back(si);
        }
        if (dl < 0.0) {
            left[si] += dl;
            checked[si] = withWarmBit(checked[si], left[si]);
        }
        const Vec3 c = (dl / l) * d;
        ++corrections;
        if constexpr (kPlanes) {
            if (wa > 0.0) shift(a, keepAbove(a, wa * c, x));
            if (wb > 0.0) shift(b, keepAbove(b, -wb * c, x));
            // A carried end's body moves its point by its share along the spring (a by +c,
            // b by -c), and every particle it carries with it.
            for (int end = 0; end < 2; ++end) {
                if (carriedAt[end] < 0) continue;
                const std::int32_t m = planes_->carried[std::size_t(carriedAt[end])].mover;
                const Vec3 n = (end == 0 ? -dl / l : dl / l) * d; // take(1, n) moves it by -n
                if (planes_->movers[std::size_t(m)].take(1.0, n, carriedLever[end]))
                    moveCarried(m, x, shift);
            }
            holdTriangles(a, x, shift);
            holdTriangles(b, x, shift);
        } else {
            if (wa > 0.0) shift(a, wa * c);
            if (wb > 0.0) shift(b, -wb * c);
        }
        if constexpr (kRecordHeld) {
            if (wa == 0.0) pullHeld(a, c);
            if (wb == 0.0) pullHeld(b, -c);
        }
    }
    st.work += order_.size();
    st.corrections += corrections;
    return nd;
}

void StrainLimiter::checkMoved(const ClothTopology& topology, const std::vector<double>& invMass,
                               const std::vector<double>& stiffness, const std::vector<Vec3>& x,
                               std::size_t movedCount, StrainLimitStats& st) {
    // The springs of every particle the wave moved are checked once (a particle moved by
    // several corrections is looked at once, from where it ended). The check reads the spring
    // from the particle's adjacency (neighbour, 1 / L0^2 side by side). The loop runs without
    // data-dependent branches (which spring a particle shares with a particle moved earlier,
    // and which springs leave the band, follow no pattern the processor could predict): every
    // spring is measured, a spring seen already this wave counts nothing, and candidates are
    // appended by adding 0 or 1 to the count. (A spring queued for the next wave was queued
    // after its check in this loop: the stamp alone keeps it from being looked at twice.)
    const Index* offp = topology.adjacencyOffsets().data();
    const Index* sprp = topology.adjacentSprings().data();
    const Index* nbrp = topology.adjacentParticles().data();
    const double* inv2p = topology.springLayout().adjacentInverseSquaredRest.data();
    const double* xp = x[0].data();
    const Index* dirty = dirty_.data();
    std::uint32_t* seen = checkedAt_.data();
    const std::uint32_t mark = stamp_ << 1; // the stamp as checkedAt_ holds it
    const double up = upper2_, low = lower2_;
    std::size_t evaluated = 0, found = 0;
    Index* cand = candidates_.data();
    for (std::size_t m = 0; m < movedCount; ++m) {
        const std::size_t e = dirty[m];
        const double ex = xp[3 * e], ey = xp[3 * e + 1], ez = xp[3 * e + 2];
        const std::size_t end = offp[e + 1];
        for (std::size_t k = offp[e]; k < end; ++k) {
            const std::size_t si = sprp[k];
            const std::uint32_t word = seen[si];
            const std::size_t fresh = (word & ~kWarmBit) != mark;
            seen[si] = mark | (word & kWarmBit);
            const double* xo = xp + 3 * std::size_t(nbrp[k]);
            const double dx = xo[0] - ex, dy = xo[1] - ey, dz = xo[2] - ez;
            const double ratio2 = detail::squaredLengthRatio(dx, dy, dz, inv2p[k]);
            // needs(si, ratio2)
            const std::size_t need = (ratio2 > up) | ((ratio2 < low) & (word & kWarmBit));
            cand[found] = static_cast<Index>(k);
            found += fresh & need;
            evaluated += fresh;
        }
    }
    st.work += evaluated;
    // The candidates (a few per wave) are measured again from the spring's ends: the same
    // (l / L0)^2 (the squares do not see the direction).
    const Spring* spring = topology.springs().data();
    const double* w = invMass.data();
    for (std::size_t c = 0; c < found; ++c) {
        const Index k = cand[c];
        const Spring& sp = spring[sprp[k]];
        if (!linked(sp.a, sp.b, w[sp.a], w[sp.b])) continue;
        const double* xa = xp + 3 * std::size_t(sp.a);
        const double* xb = xp + 3 * std::size_t(sp.b);
        const double dx = xa[0] - xb[0], dy = xa[1] - xb[1], dz = xa[2] - xb[2];
        queue(sprp[k], detail::squaredLengthRatio(dx, dy, dz, inv2p[k]), sp.restLength, stiffness);
    }
}

void StrainLimiter::runWaves(const ClothTopology& topology, const std::vector<double>& invMass,
                             const std::vector<double>& stiffness, const LimiterSettings& s,
                             std::vector<Vec3>& x, StrainLimitStats& st) {
    const auto& springs = topology.springs();
    const std::size_t cap =
        static_cast<std::size_t>(s.maxRounds) * std::max<std::size_t>(springs.size(), 1);
    dirty_.resize(x.size() + 1); // every particle at most once per wave (+1: the last write)
    const std::size_t apartCheck =
        static_cast<std::size_t>(kApartCheck) * std::max<std::size_t>(springs.size(), 1);
    bool apartChecked = false;
    while (!next_.empty()) {
        if (st.work > cap) {
            st.capHit = true;
            break;
        }
        if (!apartChecked && st.work > apartCheck && cap > apartCheck) {
            apartChecked = true;
            if (pinsApart(topology, invMass, x)) {
                st.capHit = true;
                st.pinsApart = true;
                break;
            }
        }
        wave_.swap(next_);
        next_.clear();
        ++st.rounds;
        // A walk still going after kLightenAfter waves with a free body in it: the body
        // counts lighter wave by wave (ContactPlanes::Mover::lighten).
        if (planes_ && st.rounds > kLightenAfter)
            for (ContactPlanes::Mover& m : planes_->movers)
                m.lighten = std::min(kMaxLighten, m.lighten * kLightenRate);
        if (++stamp_ == kStampEnd) { // the stamp wrapped: forget every old one
            for (std::uint32_t& c : checkedAt_)
                c &= kWarmBit;
            std::fill(dirtyAt_.begin(), dirtyAt_.end(), 0u);
            stamp_ = 1;
        }
        // Most stressed first: spring tension k (l - L0) when queued, ties by index (one
        // integer per spring, see waveKey: the comparisons read no other array).
        order_.clear();
        for (std::uint32_t si : wave_) {
            queued_[si] = 0;
            order_.push_back(waveKey(key_[si], si));
        }
        std::sort(order_.begin(), order_.end());
        std::size_t moved = 0;
        if (recordHeld_) {
            moved = planes_ ? correctWave<true, true>(springs, invMass, x, st)
                            : correctWave<false, true>(springs, invMass, x, st);
        } else {
            moved = planes_ ? correctWave<true, false>(springs, invMass, x, st)
                            : correctWave<false, false>(springs, invMass, x, st);
        }
        checkMoved(topology, invMass, stiffness, x, moved, st);
    }
    for (std::uint32_t si : next_)
        queued_[si] = 0;
    next_.clear();
}

bool StrainLimiter::pinsApart(const ClothTopology& topology, const std::vector<double>& invMass,
                              const std::vector<Vec3>& x) {
    auto& list = pinScratch_;
    heldParticles(invMass, list);
    if (list.size() < 2 || list.size() > kMaxApartPins) return false;
    const std::size_t p = list.size();
    if (list != pinList_) {
        // Dijkstra through the springs' rest lengths from each held particle, until every
        // other held particle is settled. A spring whose ends are both held is no link: the
        // walk never corrects it (nothing of it can move), so it does not stop the walk from
        // holding the others (a banner's spring between two posts pulled apart by a hit stopped
        // every walk of the hit, which left the rest of the banner at 0.110-0.115).
        pinList_ = list;
        pinPath_.assign(p * p, std::numeric_limits<double>::infinity());
        const std::size_t n = topology.particleCount();
        const auto& off = topology.adjacencyOffsets();
        const auto& nbr = topology.adjacentParticles();
        const auto& adjSpring = topology.adjacentSprings();
        const auto& springs = topology.springs();
        std::vector<std::int32_t> slot(n, -1);
        for (std::size_t k = 0; k < p; ++k)
            slot[pinList_[k]] = static_cast<std::int32_t>(k);
        std::vector<double> dist(n);
        using Item = std::pair<double, Index>;
        std::priority_queue<Item, std::vector<Item>, std::greater<Item>> front;
        for (std::size_t k = 0; k < p; ++k) {
            std::fill(dist.begin(), dist.end(), std::numeric_limits<double>::infinity());
            dist[pinList_[k]] = 0.0;
            front.push({0.0, pinList_[k]});
            std::size_t settled = 0;
            while (!front.empty() && settled < p) {
                const auto [d, a] = front.top();
                front.pop();
                if (d > dist[a]) continue;
                if (slot[a] >= 0) {
                    pinPath_[k * p + std::size_t(slot[a])] = d;
                    ++settled;
                }
                for (Index e = off[a]; e < off[a + 1]; ++e) {
                    if (invMass[a] == 0.0 && invMass[nbr[e]] == 0.0) continue;
                    if (const double de = d + springs[adjSpring[e]].restLength; de < dist[nbr[e]]) {
                        dist[nbr[e]] = de;
                        front.push({dist[nbr[e]], nbr[e]});
                    }
                }
            }
            front = decltype(front)();
        }
    }
    const double upper = std::sqrt(upper2_);
    for (std::size_t a = 0; a < p; ++a)
        for (std::size_t b = a + 1; b < p; ++b) {
            const double reach = upper * pinPath_[a * p + b];
            if ((x[pinList_[b]] - x[pinList_[a]]).squaredNorm() > reach * reach) return true;
        }
    return false;
}

// --- comparison limiters ----------------------------------------------------------------------

StrainLimitStats limitStrainProvot(const ClothTopology& topology,
                                   const std::vector<double>& invMass, const LimiterSettings& s,
                                   std::vector<Vec3>& x) {
    StrainLimitStats stats;
    const double stretchLimit = 1.0 + s.maxStrain;
    const double stopLimit = 1.0 + s.maxStrain + limiterBand(s);
    stats.maxStrainBefore = maxSpringStrain(topology, x);
    stats.maxStrainAfter = stats.maxStrainBefore;
    stats.work = topology.springCount();
    if (stats.maxStrainBefore + 1.0 <= stopLimit) return stats;
    for (int sweep = 0; sweep < s.maxRounds; ++sweep) {
        for (const Spring& sp : topology.springs()) {
            const double wa = invMass[sp.a], wb = invMass[sp.b];
            const Vec3 d = x[sp.b] - x[sp.a];
            const double l = d.norm();
            const double lmax = stretchLimit * sp.restLength;
            if (l <= lmax || wa + wb == 0.0) continue;
            const Vec3 corr = ((l - lmax) / (l * (wa + wb))) * d;
            x[sp.a] += wa * corr;
            x[sp.b] -= wb * corr;
            ++stats.corrections;
        }
        stats.rounds = sweep + 1;
        stats.maxStrainAfter = maxSpringStrain(topology, x);
        stats.work += 2 * topology.springCount();
        if (stats.maxStrainAfter + 1.0 <= stopLimit) return stats;
    }
    stats.capHit = true;
    return stats;
}

StrainLimitStats limitStrainOneSided(const ClothTopology& topology,
                                     const std::vector<double>& invMass,
                                     const std::vector<double>& stiffness, const LimiterSettings& s,
                                     std::vector<Vec3>& x) {
    StrainLimitStats stats;
    const double stretchLimit = 1.0 + s.maxStrain;
    const double stopLimit = 1.0 + s.maxStrain + limiterBand(s);
    const auto& springs = topology.springs();
    const auto& off = topology.adjacencyOffsets();
    const auto& nbr = topology.adjacentParticles();
    const auto& adjSpring = topology.adjacentSprings();
    const std::size_t n = x.size();
    stats.maxStrainBefore = maxSpringStrain(topology, x);
    stats.maxStrainAfter = stats.maxStrainBefore;
    stats.work = springs.size();
    if (stats.maxStrainBefore + 1.0 <= stopLimit) return stats;
    // Stress: the spring tension a particle receives; pinned particles first; ties by index.
    std::vector<double> key(n, 0.0);
    for (std::size_t si = 0; si < springs.size(); ++si) {
        const Spring& sp = springs[si];
        const double t = stiffness[si] * std::abs((x[sp.b] - x[sp.a]).norm() - sp.restLength);
        key[sp.a] += t;
        key[sp.b] += t;
    }
    for (std::size_t i = 0; i < n; ++i)
        if (invMass[i] == 0.0) key[i] = std::numeric_limits<double>::infinity();
    std::vector<Index> order(n);
    std::iota(order.begin(), order.end(), Index{0});
    std::sort(order.begin(), order.end(),
              [&](Index a, Index b) { return key[a] != key[b] ? key[a] > key[b] : a < b; });
    std::vector<unsigned char> fixed(n);
    for (int round = 0; round < s.maxRounds; ++round) {
        for (std::size_t i = 0; i < n; ++i)
            fixed[i] = invMass[i] == 0.0;
        for (Index p : order) {
            for (Index k = off[p]; k < off[p + 1]; ++k) {
                const Index q = nbr[k];
                if (fixed[q]) continue;
                ++stats.work;
                const Vec3 d = x[q] - x[p];
                const double l = d.norm(), lmax = stretchLimit * springs[adjSpring[k]].restLength;
                if (l <= lmax) continue;
                x[q] = x[p] + (lmax / l) * d; // pull q the whole way toward p
                fixed[q] = 1;
                ++stats.corrections;
            }
            fixed[p] = 1;
        }
        stats.rounds = round + 1;
        stats.maxStrainAfter = maxSpringStrain(topology, x);
        stats.work += springs.size();
        if (stats.maxStrainAfter + 1.0 <= stopLimit) return stats;
    }
    stats.capHit = true;
    return stats;
}

} // namespace drape
