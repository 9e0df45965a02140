// canonical_stages: times the canonical-form stages alone (frame, conditions,
// diffeomorphism with T, l and T^-1) on the issue 6 families, with r given by the
// construction instead of the observability stage (whose Lie chain dominates the dense
// family and is measured by run_check_bench.sh):
//
//   canonical_stages FAMILY N [N ...]      FAMILY: nested or dense
//
// r = tau_1 = dx/dz_1: -e_n for nested (x_n = -z_1 + ...), -M^-1 e_n = (0,..,0,1,-1) for dense.
// Prints one line per size: per-stage ms, T^-1 kind and whether the model is linearizable.
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "analysis/canonical.hpp"
#include "families.hpp"
#include "front/parse.hpp"

using namespace obsynth;

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: canonical_stages nested|dense N [N ...]\n");
    return 1;
  }
  const auto family = bench::parse_family(argv[1]);
  if (!family || (*family != bench::Family::nested && *family != bench::Family::dense)) {
    std::fprintf(stderr, "canonical_stages: family must be nested or dense\n");
    return 1;
  }
  for (int a = 2; a < argc; ++a) {
    const int n = std::atoi(argv[a]);
    if (n < 2 || n > 16) {
      std::fprintf(stderr, "canonical_stages: size %s not in 2..16\n", argv[a]);
      return 1;
    }
    const Model m =
        parse_model(bench::family_model(*family, n), bench::model_file_name(*family, n));
    Observability ob;
    ob.n = static_cast<std::size_t>(n);
    ob.p = 1;
    ob.generic_rank = ob.n;
    ob.det = 1;
    ob.last_row_cofactors.assign(ob.n, 0);
    if (*family == bench::Family::nested) {
      ob.last_row_cofactors[ob.n - 1] = -1;
    } else {
      ob.last_row_cofactors[ob.n - 2] = 1;
      ob.last_row_cofactors[ob.n - 1] = -1;
    }
    BudgetLimits limits;
    limits.stage_seconds = 600;
    Budget budget(limits);
    const auto start = std::chrono::steady_clock::now();
    const CanonicalForm cf = analyse_canonical(m, ob, budget);
    const double total =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    std::string stages;
    for (const auto& [stage, ms] : budget.timings_ms())
      stages += fmt::format(" {} {:.1f} ms,", stage, ms);
    std::printf("%s n=%d: total %.1f ms;%s linearizable %s, T %s, T^-1 %s\n", argv[1], n, total,
                stages.c_str(), cf.linearizable ? "yes" : "no", availability_name(cf.T_kind),
                availability_name(cf.T_inverse_kind));
  }
  return 0;
}
