// pin_aba: time pinocchio's own aba, rnea and crba on a URDF model.
//
// Usage: pin_aba [--blocks=N] [--block-ms=MS] [--seed=S] [--calls=N] <urdf> [locked_joint[=value] ...]
//
// Locked joints are removed with pinocchio::buildReducedModel and held at the
// neutral configuration (0 for revolute and prismatic joints), or at `value` when
// given as name=value (one-coordinate joints only).  q, v, tau are
// drawn once from a fixed seed (q uniform in [-1, 1] then normalized, v and tau
// uniform in [-1, 1]).  Each algorithm is timed as the median over `blocks`
// blocks of calls, each block sized to take about `block-ms` milliseconds,
// after a warm-up.  Prints one JSON line on stdout.  With --calls=N it only calls
// aba N times, untimed (for an instruction counter: callgrind's totals at two N
// differ by (N2 - N1) calls, the model loading cancels).
//
// Built with PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION (the default, as a CMake
// user of pinocchio::pinocchio gets it) the algorithms run from the wheel's
// precompiled libpinocchio_default.so; built without it, they are instantiated
// from the headers in this translation unit with this program's flags.  The
// "pin_mode" key of the output says which.

#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>
#include <pinocchio/parsers/urdf.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <exception>
#include <random>
#include <string>
#include <vector>

namespace
{

#ifdef PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION
const char * const kPinMode = "library";
#else
const char * const kPinMode = "header";
#endif

volatile double g_sink = 0.0;

double now_ns()
{
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return 1e9 * static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec);
}

struct Timing
{
  double ns_per_call;
  long calls_per_block;
};

// Median ns per call of f() over `blocks` blocks of ~block_ms each.
template<typename F>
Timing time_median(F && f, int blocks, double block_ms)
{
  const double target_ns = block_ms * 1e6;
  for (int i = 0; i < 100; ++i)  // first calls: lazy symbol binding, cold caches
    f();
  long n = 1;
  for (;;)  // calibrate: double n until one block takes at least target_ns
  {
    const double t0 = now_ns();
    for (long i = 0; i < n; ++i)
      f();
    const double dt = now_ns() - t0;
    if (dt >= target_ns || n > (1L << 40))
      break;
    if (dt > 0.1 * target_ns)
      n = std::max(n + 1, static_cast<long>(static_cast<double>(n) * target_ns / dt));
    else
      n *= 2;
  }
  for (int w = 0; w < 3; ++w)  // warm-up
    for (long i = 0; i < n; ++i)
      f();
  std::vector<double> per_call(static_cast<size_t>(blocks));
  for (int b = 0; b < blocks; ++b)
  {
    const double t0 = now_ns();
    for (long i = 0; i < n; ++i)
      f();
    per_call[static_cast<size_t>(b)] = (now_ns() - t0) / static_cast<double>(n);
  }
  std::sort(per_call.begin(), per_call.end());
  const size_t m = per_call.size();
  const double med =
    (m % 2) ? per_call[m / 2] : 0.5 * (per_call[m / 2 - 1] + per_call[m / 2]);
  return Timing{med, n};
}

std::string json_escape(const std::string & s)
{
  std::string out;
  for (char c : s)
  {
    if (c == '"' || c == '\\')
    {
      out += '\\';
      out += c;
    }
    else if (static_cast<unsigned char>(c) < 0x20)
    {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(c)));
      out += buf;
    }
    else
      out += c;
  }
  return out;
}

int usage(const char * argv0)
{
  std::fprintf(
    stderr, "usage: %s [--blocks=N] [--block-ms=MS] [--seed=S] <urdf> [locked_joint[=value] ...]\n",
    argv0);
  return 2;
}

} // namespace

int main(int argc, char ** argv)
{
  int blocks = 51;
  double block_ms = 15.0;
  unsigned seed = 12345u;
  long calls = 0;
  std::vector<std::string> positional;
  for (int i = 1; i < argc; ++i)
  {
    const char * a = argv[i];
    if (std::strncmp(a, "--blocks=", 9) == 0)
      blocks = std::atoi(a + 9);
    else if (std::strncmp(a, "--block-ms=", 11) == 0)
      block_ms = std::atof(a + 11);
    else if (std::strncmp(a, "--seed=", 7) == 0)
      seed = static_cast<unsigned>(std::strtoul(a + 7, nullptr, 10));
    else if (std::strncmp(a, "--calls=", 8) == 0)
      calls = std::atol(a + 8);
    else if (std::strncmp(a, "--", 2) == 0)
    {
      std::fprintf(stderr, "pin_aba: unknown option '%s'\n", a);
      return usage(argv[0]);
    }
    else
      positional.emplace_back(a);
  }
  if (positional.empty())
    return usage(argv[0]);
  if (blocks < 1 || !(block_ms > 0.0))
  {
    std::fprintf(stderr, "pin_aba: --blocks must be >= 1 and --block-ms > 0\n");
    return 2;
  }
  const std::string urdf = positional[0];

  pinocchio::Model full;
  try
  {
    pinocchio::urdf::buildModel(urdf, full);
  }
  catch (const std::exception & e)
  {
    std::fprintf(stderr, "pin_aba: cannot load URDF '%s': %s\n", urdf.c_str(), e.what());
    return 1;
  }

  // locked joints: "name" (held at the neutral configuration, 0 for revolute/prismatic)
  // or "name=value" (a one-coordinate joint held at value)
  std::vector<pinocchio::JointIndex> locked;
  std::vector<std::string> locked_names;
  Eigen::VectorXd q_lock = pinocchio::neutral(full);
  for (size_t i = 1; i < positional.size(); ++i)
  {
    std::string name = positional[i];
    const size_t eq = name.find('=');
    double value = 0.0;
    const bool has_value = eq != std::string::npos;
    if (has_value)
    {
      const std::string text = name.substr(eq + 1);
      char * end = nullptr;
      value = std::strtod(text.c_str(), &end);
      name = name.substr(0, eq);
      if (text.empty() || *end != '\0')
      {
        std::fprintf(
          stderr, "pin_aba: locked joint '%s': value '%s' is not a number\n", name.c_str(),
          text.c_str());
        return 1;
      }
    }
    if (!full.existJointName(name))
    {
      std::fprintf(stderr, "pin_aba: no joint named '%s' in '%s'\n", name.c_str(), urdf.c_str());
      return 1;
    }
    const pinocchio::JointIndex id = full.getJointId(name);
    if (has_value)
    {
      if (full.nqs[id] != 1)
      {
        std::fprintf(
          stderr, "pin_aba: locked joint '%s' has %d coordinates; name=value needs 1\n",
          name.c_str(), full.nqs[id]);
        return 1;
      }
      q_lock[full.idx_qs[id]] = value;
    }
    locked.push_back(id);
    locked_names.push_back(name);
  }
  pinocchio::Model model;
  if (locked.empty())
    model = full;
  else
    pinocchio::buildReducedModel(full, locked, q_lock, model);
  pinocchio::Data data(model);

  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  Eigen::VectorXd q(model.nq), v(model.nv), tau(model.nv), a(model.nv);
  for (Eigen::Index i = 0; i < q.size(); ++i)
    q[i] = uni(rng);
  pinocchio::normalize(model, q);
  for (Eigen::Index i = 0; i < v.size(); ++i)
    v[i] = uni(rng);
  for (Eigen::Index i = 0; i < tau.size(); ++i)
    tau[i] = uni(rng);
  for (Eigen::Index i = 0; i < a.size(); ++i)
    a[i] = uni(rng);

  // Eigen::Ref arguments match the explicit instantiations of the library.
  typedef Eigen::Ref<const Eigen::VectorXd> CRef;
  const CRef rq(q), rv(v), rtau(tau), ra(a);

  if (calls > 0)
  {
    for (long i = 0; i < calls; ++i)
    {
      pinocchio::aba(model, data, rq, rv, rtau, pinocchio::Convention::LOCAL);
      g_sink = g_sink + data.ddq[0];
    }
    std::printf("{\"calls\": %ld, \"nv\": %d, \"pin_mode\": \"%s\"}\n", calls, model.nv, kPinMode);
    return 0;
  }

  const Timing t_aba = time_median(
    [&]() {
      pinocchio::aba(model, data, rq, rv, rtau, pinocchio::Convention::LOCAL);
      g_sink = g_sink + data.ddq[0];
    },
    blocks, block_ms);
  const Timing t_rnea = time_median(
    [&]() {
      pinocchio::rnea(model, data, rq, rv, ra);
      g_sink = g_sink + data.tau[0];
    },
    blocks, block_ms);
  const Timing t_crba = time_median(
    [&]() {
      pinocchio::crba(model, data, rq, pinocchio::Convention::LOCAL);
      g_sink = g_sink + data.M(0, 0);
    },
    blocks, block_ms);

  std::string locked_json = "[";
  for (size_t i = 0; i < locked_names.size(); ++i)
  {
    if (i > 0)
      locked_json += ", ";
    locked_json += "\"" + json_escape(locked_names[i]) + "\"";
  }
  locked_json += "]";

  std::printf(
    "{\"urdf\": \"%s\", \"locked_joints\": %s, \"nq\": %d, \"nv\": %d, \"ns_aba\": %.6g, "
    "\"ns_rnea\": %.6g, \"ns_crba\": %.6g, \"blocks\": %d, \"calls_per_block_aba\": %ld, "
    "\"pin_mode\": \"%s\", \"pinocchio_version\": \"%s\"}\n",
    json_escape(urdf).c_str(), locked_json.c_str(), model.nq, model.nv, t_aba.ns_per_call,
    t_rnea.ns_per_call, t_crba.ns_per_call, blocks, t_aba.calls_per_block, kPinMode,
    PINOCCHIO_VERSION);
  return 0;
}
