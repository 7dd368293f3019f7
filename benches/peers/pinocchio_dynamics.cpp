// Pinocchio's rigid-body algorithms timed with the statistic of `gelenk bench dynamics`: the
// median over rounds of the mean ns per call over one pass through 1000 random states, after
// 200 ms of warm-up. Built and run by benches/dynamics_peers.py, header-only (Pinocchio's
// headers from `pip install pin`, compiled with g++ -O3 -march=native like this repository's
// builds), so nothing links against the wheel's shared libraries.
//
// The model comes from a text file that benches/dynamics_peers.py writes with Pinocchio's own
// URDF parser (through its Python bindings); one line per joint after the header line `nq nv
// njoints`:
//   parent type ax ay az  R00 R01 R02 R10 R11 R12 R20 R21 R22  px py pz  mass cx cy cz
//   Ixx Ixy Ixz Iyx Iyy Iyz Izx Izy Izz
// with `type` Pinocchio's joint short name (JointModelRZ, JointModelFreeFlyer, ...), (ax, ay,
// az) the axis of an unaligned joint, R and p the joint placement in its parent joint's frame,
// and the body's inertia about its joint frame (mass, centre of mass, rotational inertia about
// the centre of mass); then two lines of nq numbers, the lower and upper bounds random
// configurations are drawn within (the URDF's limits where finite, as `gelenk bench dynamics`
// draws them).
//
// Prints one JSON line: {"nq","nv","rnea_ns","crba_local_ns","crba_world_ns",
// "crba_world_symmetric_ns","aba_local_ns","aba_world_ns","nle_ns","mass_checksum"}.
// `crba_local_ns` and `crba_world_ns` are `pinocchio::crba` in its two conventions, which write
// M's upper triangle only: LOCAL (the default) computes M alone (as
// `gelenk::algorithms::mass_matrix` does), WORLD also the joints' world poses `data.oMi`, the
// world Jacobian `data.J` and the centroidal map `data.Ag`.
// `crba_world_symmetric_ns` is WORLD followed by the copy of the strict upper triangle into the
// lower one: what `gelenk::algorithms::crba` computes (world poses, world Jacobian columns, the
// whole M). `aba_local_ns` and `aba_world_ns`: `pinocchio::aba` in its two conventions.
// `mass_checksum` is the sum of M's upper-triangle entries at the neutral configuration, for
// the script's check that this model is Pinocchio's.
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

using Clock = std::chrono::steady_clock;

template <typename F>
double median_ns(int rounds, int pool, F f) {
  const auto warm = Clock::now();
  while (Clock::now() - warm < std::chrono::milliseconds(200))
    for (int k = 0; k < pool; ++k) f(k);
  std::vector<double> per_call;
  for (int r = 0; r < rounds; ++r) {
    const auto start = Clock::now();
    for (int k = 0; k < pool; ++k) f(k);
    const std::chrono::duration<double, std::nano> elapsed = Clock::now() - start;
    per_call.push_back(elapsed.count() / pool);
  }
  std::sort(per_call.begin(), per_call.end());
  return per_call[per_call.size() / 2];
}

static pinocchio::JointModel joint_of(const std::string& type, const Eigen::Vector3d& axis) {
  using namespace pinocchio;
  if (type == "JointModelRX") return JointModelRX();
  if (type == "JointModelRY") return JointModelRY();
  if (type == "JointModelRZ") return JointModelRZ();
  if (type == "JointModelRevoluteUnaligned") return JointModelRevoluteUnaligned(axis);
  if (type == "JointModelRUBX") return JointModelRUBX();
  if (type == "JointModelRUBY") return JointModelRUBY();
  if (type == "JointModelRUBZ") return JointModelRUBZ();
  if (type == "JointModelRevoluteUnboundedUnaligned")
    return JointModelRevoluteUnboundedUnaligned(axis);
  if (type == "JointModelPX") return JointModelPX();
  if (type == "JointModelPY") return JointModelPY();
  if (type == "JointModelPZ") return JointModelPZ();
  if (type == "JointModelPrismaticUnaligned") return JointModelPrismaticUnaligned(axis);
  if (type == "JointModelFreeFlyer") return JointModelFreeFlyer();
  if (type == "JointModelSpherical") return JointModelSpherical();
  std::fprintf(stderr, "pinocchio_dynamics: joint type %s is not handled\n", type.c_str());
  std::exit(2);
}

static pinocchio::Model read_model(const char* path) {
  std::ifstream in(path);
  if (!in) {
    std::fprintf(stderr, "pinocchio_dynamics: cannot read %s\n", path);
    std::exit(2);
  }
  int nq = 0, nv = 0, njoints = 0;
  in >> nq >> nv >> njoints;
  pinocchio::Model model;
  for (int i = 1; i < njoints; ++i) {
    std::size_t parent;
    std::string type;
    Eigen::Vector3d axis, translation, com;
    Eigen::Matrix3d rotation, inertia;
    double mass;
    in >> parent >> type >> axis[0] >> axis[1] >> axis[2];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) in >> rotation(r, c);
    in >> translation[0] >> translation[1] >> translation[2] >> mass >> com[0] >> com[1] >> com[2];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) in >> inertia(r, c);
    if (!in) {
      std::fprintf(stderr, "pinocchio_dynamics: %s: malformed joint line %d\n", path, i);
      std::exit(2);
    }
    const auto id = model.addJoint(parent, joint_of(type, axis), pinocchio::SE3(rotation, translation),
                                   "joint" + std::to_string(i));
    model.appendBodyToJoint(id, pinocchio::Inertia(mass, com, inertia), pinocchio::SE3::Identity());
  }
  model.lowerPositionLimit.resize(model.nq);
  model.upperPositionLimit.resize(model.nq);
  for (int k = 0; k < model.nq; ++k) in >> model.lowerPositionLimit[k];
  for (int k = 0; k < model.nq; ++k) in >> model.upperPositionLimit[k];
  if (!in) {
    std::fprintf(stderr, "pinocchio_dynamics: %s: malformed limits\n", path);
    std::exit(2);
  }
  if (model.nq != nq || model.nv != nv) {
    std::fprintf(stderr, "pinocchio_dynamics: %s: built nq %d nv %d, file says %d %d\n", path,
                 model.nq, model.nv, nq, nv);
    std::exit(2);
  }
  return model;
}

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: pinocchio_dynamics MODEL.txt [--rounds N]\n");
    return 2;
  }
  int rounds = 51;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--rounds" && i + 1 < argc) rounds = std::atoi(argv[++i]);
  }
  const pinocchio::Model model = read_model(argv[1]);
  pinocchio::Data data(model);
  const int pool = 1000;
  std::srand(7);
  std::vector<Eigen::VectorXd> qs, vs, as;
  for (int k = 0; k < pool; ++k) {
    qs.push_back(pinocchio::randomConfiguration(model));
    vs.push_back(Eigen::VectorXd::Random(model.nv));
    as.push_back(Eigen::VectorXd::Random(model.nv));
  }
  pinocchio::crba(model, data, pinocchio::neutral(model), pinocchio::Convention::WORLD);
  const double mass_checksum = data.M.triangularView<Eigen::Upper>().toDenseMatrix().sum();

  volatile double sink = 0;
  const double rnea_ns = median_ns(rounds, pool, [&](int k) {
    sink = sink + pinocchio::rnea(model, data, qs[k], vs[k], as[k])[0];
  });
  const double crba_local_ns = median_ns(rounds, pool, [&](int k) {
    sink = sink + pinocchio::crba(model, data, qs[k], pinocchio::Convention::LOCAL)(0, 0);
  });
  const double crba_world_ns = median_ns(rounds, pool, [&](int k) {
    sink = sink + pinocchio::crba(model, data, qs[k], pinocchio::Convention::WORLD)(0, 0);
  });
  const double crba_world_symmetric_ns = median_ns(rounds, pool, [&](int k) {
    pinocchio::crba(model, data, qs[k], pinocchio::Convention::WORLD);
    data.M.triangularView<Eigen::StrictlyLower>() =
        data.M.transpose().triangularView<Eigen::StrictlyLower>();
    sink = sink + data.M(model.nv - 1, 0);
  });
  const double aba_local_ns = median_ns(rounds, pool, [&](int k) {
    sink = sink + pinocchio::aba(model, data, qs[k], vs[k], as[k], pinocchio::Convention::LOCAL)[0];
  });
  const double aba_world_ns = median_ns(rounds, pool, [&](int k) {
    sink = sink + pinocchio::aba(model, data, qs[k], vs[k], as[k], pinocchio::Convention::WORLD)[0];
  });
  const double nle_ns = median_ns(rounds, pool, [&](int k) {
    sink = sink + pinocchio::nonLinearEffects(model, data, qs[k], vs[k])[0];
  });
  std::printf(
      "{\"nq\": %d, \"nv\": %d, \"rnea_ns\": %.1f, \"crba_local_ns\": %.1f, \"crba_world_ns\": %.1f, "
      "\"crba_world_symmetric_ns\": %.1f, \"aba_local_ns\": %.1f, \"aba_world_ns\": %.1f, "
      "\"nle_ns\": %.1f, \"mass_checksum\": %.17g}\n",
      model.nq, model.nv, rnea_ns, crba_local_ns, crba_world_ns, crba_world_symmetric_ns,
      aba_local_ns, aba_world_ns, nle_ns, mass_checksum);
  return 0;
}
