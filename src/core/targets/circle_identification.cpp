// Stage 3 of TargetCentroider::DetectMono: identification of circles. With
// a view, every listed circle is projected into the image and a candidate
// takes the ID of the nearest within circle_id_gate of its radius; after the
// measurement one target per marker is kept. (A board of unlisted markers
// is numbered by its layout: board_layout.h.)
#include "centroider_stages.h"

namespace slope_monitor {
namespace targets {
namespace detail {
namespace {

// Semi-major axis [px] of the image of a circle (diameter [m], centre and
// normal in site): half the longest chord between 36 projected rim points;
// 0 when a rim point does not project.
double ProjectedSemiMajor(const ViewGeometry& view, const Eigen::Vector3d& centre,
                          const Eigen::Vector3d& normal, double diameter) {
  const Eigen::Vector3d n = normal.normalized(), u = n.unitOrthogonal(), v = n.cross(u);
  std::array<Eigen::Vector2d, 36> p;
  for (int i = 0; i < 36; ++i) {
    const double a = 2 * M_PI * i / 36;
    if (!view.camera.Project(view.pose,
                             centre + 0.5 * diameter * (std::cos(a) * u + std::sin(a) * v), &p[i]))
      return 0.0;
  }
  double longest = 0.0;
  for (int i = 0; i < 36; ++i)
    for (int j = i + 1; j < 36; ++j) longest = std::max(longest, (p[i] - p[j]).norm());
  return 0.5 * longest;
}

}  // namespace

std::vector<ExpectedCircle> ProjectListedCircles(const ViewGeometry* view,
                                                 const io::TargetList& targets) {
  std::vector<ExpectedCircle> expected;
  if (!view) return expected;
  for (const auto& s : targets.targets()) {
    if (s.family != "circle" || !s.position) continue;
    Eigen::Vector2d px;
    if (!view->camera.Project(view->pose, *s.position, &px)) continue;
    Eigen::Vector3d n = s.normal ? *s.normal : Eigen::Vector3d(0, 0, 1);
    Eigen::Vector2d edge;
    view->camera.Project(view->pose, *s.position + 0.5 * s.size * n.unitOrthogonal(), &edge);
    expected.push_back({&s, px, (edge - px).norm(),
                        s.normal ? ProjectedSemiMajor(*view, *s.position, n, s.size) : 0.0});
  }
  return expected;
}

const ExpectedCircle* IdentifyCircle(const std::vector<ExpectedCircle>& expected, const Blob& blob,
                                     const Options& o) {
  int best = -1;
  double best_d = 1e18;
  for (size_t k = 0; k < expected.size(); ++k) {
    const double d = (expected[k].px - blob.centre).norm();
    if (d < best_d) {
      best_d = d;
      best = static_cast<int>(k);
    }
  }
  if (best >= 0 && best_d < o.circle_id_gate * std::max(expected[best].radius_px, 2.0) + 1.0)
    return &expected[best];
  return nullptr;
}

// One target per marker: a circle whose centre lies within another circle's
// outer edge (a light gap or code segment of a ring marker, a dot inside a
// ring) is dropped in favour of the larger one (debug output: discarded,
// reason "design").
double OuterRadius(const Observation& o) { return 0.5 * o.size_px * std::max(o.ring_ratio, 1.0); }

void DropNestedCircles(Result* res) {
  std::vector<bool> drop(res->observations.size(), false);
  for (size_t i = 0; i < res->observations.size(); ++i) {
    const Observation& a = res->observations[i];
    if (a.family != "circle") continue;
    for (size_t j = 0; j < res->observations.size(); ++j) {
      const Observation& b = res->observations[j];
      if (i == j || b.family != "circle" || drop[i]) continue;
      const double ra = OuterRadius(a), rb = OuterRadius(b);
      if ((a.centre - b.centre).norm() < rb && (ra < rb || (ra == rb && i > j))) drop[i] = true;
    }
  }
  // Markers that could not be measured: inside a measured marker's outer
  // edge, the same marker seen again (another candidate of it, listed or
  // not); unlisted ones also by the same rule among them.
  std::vector<bool> drop_r(res->rejections.size(), false);
  for (size_t i = 0; i < res->rejections.size(); ++i) {
    const Rejection& a = res->rejections[i];
    if (a.family != "circle") continue;
    for (size_t j = 0; j < res->observations.size() && !drop_r[i]; ++j) {
      const Observation& b = res->observations[j];
      if (!drop[j] && b.family == "circle" && (a.where - b.centre).norm() < OuterRadius(b))
        drop_r[i] = true;
    }
    if (a.id >= 0) continue;
    for (size_t j = 0; j < res->rejections.size() && !drop_r[i]; ++j) {
      const Rejection& b = res->rejections[j];
      if (i == j || b.family != "circle") continue;
      if ((a.where - b.where).norm() < b.radius_px &&
          (a.radius_px < b.radius_px || (a.radius_px == b.radius_px && i > j)))
        drop_r[i] = true;
    }
  }
  std::vector<Rejection> kept_r;
  for (size_t i = 0; i < res->rejections.size(); ++i) {
    if (!drop_r[i]) {
      kept_r.push_back(res->rejections[i]);
      continue;
    }
    res->summary.rejects_by_reason[RejectReasonName(res->rejections[i].reason)]--;
    Rejection r = res->rejections[i];
    r.detail += " (inside the outer edge of a larger circle: one target per marker)";
    res->discarded.push_back(r);
  }
  res->rejections.swap(kept_r);
  std::vector<Observation> kept;
  for (size_t i = 0; i < res->observations.size(); ++i) {
    const Observation& o = res->observations[i];
    if (!drop[i]) {
      kept.push_back(o);
      continue;
    }
    Rejection r;
    r.family = "circle";
    r.id = o.id;
    r.where = o.centre;
    r.reason = RejectReason::kDesign;
    r.detail = "inside the outer edge of a larger circle (one target per marker)";
    res->discarded.push_back(r);
    res->summary.num_circles--;
    if (!o.role) res->summary.num_unknown--;
  }
  res->observations.swap(kept);
}

}  // namespace detail
}  // namespace targets
}  // namespace slope_monitor
