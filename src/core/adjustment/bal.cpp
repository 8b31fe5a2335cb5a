#include "slope_monitor/core/adjustment/bal.h"

#include <fstream>
#include <memory>

#include <ceres/ceres.h>

#include "slope_monitor/core/adjustment/cost_functions/snavely_reprojection_error.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {

BalProblem BalProblem::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError(Message("BAL file '", path, "' cannot be opened"));
  long nc = 0, np = 0, no = 0;
  if (!(in >> nc >> np >> no) || nc <= 0 || np <= 0 || no <= 0)
    throw IoError(Message("BAL file '", path, "': bad header (need three positive counts)"));
  // Every number takes at least one character and one separator: a file too
  // short for its declared counts is refused before anything is allocated.
  const std::streampos header_end = in.tellg();
  in.seekg(0, std::ios::end);
  const long long remaining = static_cast<long long>(in.tellg() - header_end);
  in.seekg(header_end);
  const long double needed = 2.0L * (4.0L * no + 9.0L * nc + 3.0L * np) - 1.0L;
  if (needed > remaining)
    throw IoError(Message("BAL file '", path, "': header declares ", nc, " cameras, ", np,
                          " points, ", no, " observations, which need at least ",
                          static_cast<double>(needed), " bytes; the file has ", remaining,
                          " after the header"));
  BalProblem p;
  p.cameras.resize(nc);
  p.points.resize(np);
  p.observations.resize(no);
  for (long k = 0; k < no; ++k) {
    BalObservation& o = p.observations[k];
    if (!(in >> o.camera >> o.point >> o.x >> o.y))
      throw IoError(Message("BAL file '", path, "': observation ", k, " of ", no,
                            " is missing or malformed"));
    if (o.camera < 0 || o.camera >= nc || o.point < 0 || o.point >= np)
      throw IoError(Message("BAL file '", path, "': observation ", k, " refers to camera ",
                            o.camera, " / point ", o.point, " (", nc, " cameras, ", np,
                            " points)"));
  }
  for (long c = 0; c < nc; ++c)
    for (int i = 0; i < 9; ++i)
      if (!(in >> p.cameras[c][i]))
        throw IoError(Message("BAL file '", path, "': camera ", c, " parameter ", i,
                              " is missing or malformed"));
  for (long j = 0; j < np; ++j)
    for (int i = 0; i < 3; ++i)
      if (!(in >> p.points[j][i]))
        throw IoError(Message("BAL file '", path, "': point ", j, " coordinate ", i,
                              " is missing or malformed"));
  return p;
}

double BalProblem::Cost() const {
  double cost = 0.0;
  for (const BalObservation& o : observations) {
    SnavelyReprojectionError f(o.x, o.y);
    double r[2];
    f(cameras[o.camera].data(), points[o.point].data(), r);
    cost += 0.5 * (r[0] * r[0] + r[1] * r[1]);
  }
  return cost;
}

BalReport SolveBal(BalProblem* problem, const Options& options, bool analytic_jacobians) {
  options.Check();
  std::unique_ptr<ceres::LossFunction> loss;
  if (options.loss == "huber") loss = std::make_unique<ceres::HuberLoss>(options.loss_scale);
  if (options.loss == "cauchy") loss = std::make_unique<ceres::CauchyLoss>(options.loss_scale);
  ceres::Problem::Options po;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem cp(po);
  for (const BalObservation& o : problem->observations) {
    ceres::CostFunction* cost = analytic_jacobians
                                    ? SnavelyReprojectionErrorAnalytic::Create(o.x, o.y)
                                    : SnavelyReprojectionError::Create(o.x, o.y);
    cp.AddResidualBlock(cost, loss.get(), problem->cameras[o.camera].data(),
                        problem->points[o.point].data());
  }
  std::vector<double*> points;
  for (auto& x : problem->points)
    if (cp.HasParameterBlock(x.data())) points.push_back(x.data());
  BalReport r;
  r.num_cameras = static_cast<int>(problem->cameras.size());
  r.num_points = static_cast<int>(problem->points.size());
  r.num_observations = static_cast<int>(problem->observations.size());
  r.solve = SolveCeresProblem(options, points, r.num_cameras, &cp);
  return r;
}

}  // namespace adjustment
}  // namespace slope_monitor
