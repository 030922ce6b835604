// The floor under the 2 s horizon's 10 ms budget, timed in compiled Pinocchio: the bundled mobile
// manipulator (urdf/mobile_manipulator.urdf on a planar root joint, nq 10, nv 9) integrated over
// 2 s at 1 ms by RK4 (2000 steps, 8000 evaluations), with NO constraints and no projection —
// strictly less work than the constrained horizon of benches/horizon.rs. The right-hand side is
// Pinocchio's `aba`, or `crba` + its Cholesky (`cholesky::decompose` / `solve`) on M a = τ − h
// with h from `nonLinearEffects`, whichever is faster is the floor.
//
// Built and run by tools/peers/horizon_floor.sh against the PyPI `pin` wheel (the same venv and
// flags as ../shared/tools/anchors/cpp/build.sh). Prints the best of R runs of the whole
// horizon, in ms, and the final state's norm (so the work cannot be optimized away).

#include "pinocchio/parsers/urdf.hpp"
#include "pinocchio/algorithm/aba.hpp"
#include "pinocchio/algorithm/cholesky.hpp"
#include "pinocchio/algorithm/crba.hpp"
#include "pinocchio/algorithm/joint-configuration.hpp"
#include "pinocchio/algorithm/rnea.hpp"

#include <chrono>
#include <cstdio>
#include <functional>
#include <string>

using namespace pinocchio;
typedef Eigen::VectorXd Vec;

int main(int argc, char ** argv)
{
  if (argc < 2)
  {
    std::fprintf(stderr, "usage: horizon_pin URDF [RUNS]\n");
    return 2;
  }
  const int runs = argc > 2 ? std::atoi(argv[2]) : 30;
  Model model;
  pinocchio::urdf::buildModel(argv[1], JointModelPlanar(), model);
  Data data(model);
  // The scene's initial state (params/mobile_manipulator.yaml): arm pitch 0.5, elbow 1.0,
  // wrist 0.5 rad, base at 0.2 m/s, wheels at 4 rad/s; τ = 0.
  Vec q0 = neutral(model), v0 = Vec::Zero(model.nv), tau = Vec::Zero(model.nv);
  auto set_q = [&](const char * name, double x) { q0[model.joints[model.getJointId(name)].idx_q()] = x; };
  auto set_v = [&](const char * name, double x) { v0[model.joints[model.getJointId(name)].idx_v()] = x; };
  set_q("arm_shoulder_pitch", 0.5);
  set_q("arm_elbow", 1.0);
  set_q("arm_wrist", 0.5);
  v0[0] = 0.2;
  set_v("left_wheel_joint", 4.0);
  set_v("right_wheel_joint", 4.0);

  const double dt = 1e-3;
  const int steps = 2000;
  std::function<void(const Vec &, const Vec &, Vec &)> by_aba = [&](const Vec & q, const Vec & v, Vec & a) {
    a = aba(model, data, q, v, tau);
  };
  std::function<void(const Vec &, const Vec &, Vec &)> by_crba = [&](const Vec & q, const Vec & v, Vec & a) {
    crba(model, data, q);
    data.M.triangularView<Eigen::StrictlyLower>() = data.M.transpose().triangularView<Eigen::StrictlyLower>();
    a = tau - nonLinearEffects(model, data, q, v);
    cholesky::decompose(model, data);
    cholesky::solve(model, data, a);
  };

  Vec q(model.nq), v(model.nv), k1(model.nv), k2(model.nv), k3(model.nv), k4(model.nv);
  Vec qs(model.nq), vs(model.nv), d(model.nv), v2(model.nv), v3(model.nv), v4(model.nv);
  auto horizon = [&](const std::function<void(const Vec &, const Vec &, Vec &)> & f) {
    q = q0;
    v = v0;
    for (int s = 0; s < steps; ++s)
    {
      // RK4 on the manifold: q advances by integrate(q, h · v_stage), as ours does.
      f(q, v, k1);
      integrate(model, q, v * (0.5 * dt), qs);
      vs = v + 0.5 * dt * k1;
      v2 = vs;
      f(qs, vs, k2);
      integrate(model, q, v2 * (0.5 * dt), qs);
      vs = v + 0.5 * dt * k2;
      v3 = vs;
      f(qs, vs, k3);
      integrate(model, q, v3 * dt, qs);
      vs = v + dt * k3;
      v4 = vs;
      f(qs, vs, k4);
      d = (v + 2.0 * v2 + 2.0 * v3 + v4) * (dt / 6.0);
      integrate(model, q, d, qs);
      q = qs;
      v += (k1 + 2.0 * k2 + 2.0 * k3 + k4) * (dt / 6.0);
    }
  };
  auto best_ms = [&](const std::function<void(const Vec &, const Vec &, Vec &)> & f) {
    using clk = std::chrono::steady_clock;
    horizon(f);
    double best = 1e30;
    for (int r = 0; r < runs; ++r)
    {
      auto t0 = clk::now();
      horizon(f);
      double ms = std::chrono::duration<double, std::milli>(clk::now() - t0).count();
      best = ms < best ? ms : best;
    }
    return best;
  };
  double t_aba = best_ms(by_aba);
  Vec q_aba = q, v_aba = v;
  double t_crba = best_ms(by_crba);
  std::printf("model nq %d nv %d; 2 s at 1 ms, RK4, no constraints, best of %d runs\n", model.nq, model.nv, runs);
  std::printf("aba            %.3f ms\n", t_aba);
  std::printf("crba+cholesky  %.3f ms\n", t_crba);
  std::printf("end state: |q| %.12f |v| %.12f (aba); crba differs by %.3g, %.3g\n", q_aba.norm(), v_aba.norm(),
              (q - q_aba).norm(), (v - v_aba).norm());
  return 0;
}
