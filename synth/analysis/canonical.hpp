// Linearization by output injection (seed 003 Lemma 1, Procedure 1; seed 001 Theorem 3):
// the vector field r, the frame tau_k, conditions C1-C4, the diffeomorphism T to observer
// canonical form (output last), its inverse, and the output injection l(u, y). The stages
// live in frame, conditions, diffeomorphism (T, l) and inverse (T^-1); analyse_canonical
// runs them in order.
//
// p outputs (Krener and Respondek 1985, Xia and Gao 1989): with observability indices
// k_1 + ... + k_p = n the canonical form is block Brunovsky, one block per output, output last
// in each: z_{i,1}' = l_{i,1}(u, y), z_{i,m}' = z_{i,m-1} + l_{i,m}(u, y), y_i = z_{i,k_i} + y0_i.
// In z, tau_{i,m} = d/dz_{i,m}, so the frame is built from r_i = tau_{i,1} by tau_{i,m+1} =
// [-f, tau_{i,m}]; r_i is the dual field O r_i = e_(i, k_i - 1) over O's selected rows. With
// equal indices that is the only candidate. With unequal ones the frame in z may differ from it
// along the longer blocks (by functions of y); those corrections are not searched, so a failing
// condition then refutes this frame only (CanonicalForm::frame_note). Besides the brackets, the
// outputs must read the block ends: <dh_l, tau_{i,m}> = delta_li delta_{m,k_i} (C5; implied by
// the construction when p = 1 or the indices are equal).
#pragma once

#include <ginac/ginac.h>

#include <optional>
#include <string>
#include <vector>

#include "analysis/observability.hpp"
#include "foundation/budget.hpp"
#include "front/model.hpp"
#include "symbolic/lie.hpp"
#include "symbolic/zero_test.hpp"

namespace obsynth {

struct BracketCheck {
  std::size_t i = 0, j = 0;  // 1-based frame indices; i = 0 for [g, tau_j]
  ZeroVerdict verdict = ZeroVerdict::proved;
  ExVec residual;             // the bracket itself, simplified (zero when it holds)
  std::string residual_note;  // why residual is empty: too large to print, or decided by exact
                              // evaluation at random points (conditions.cpp)
  int zero_points = 0;        // numeric verdict: sample points where every component vanished
  GiNaC::exmap witness;       // nonzero verdict: a point where the bracket is clearly nonzero
  bool holds() const { return verdict != ZeroVerdict::nonzero; }
};

enum class Completeness { global, local, unknown };
const char* completeness_name(Completeness c);

// How a map is available to later stages.
enum class Availability { symbolic, numeric, none };
const char* availability_name(Availability a);

// One step of T^-1: x_state = value, where value is in z and the states solved in earlier
// steps, obtained by solving equation T_equation(x) = z_equation (0-based indices).
struct EliminationStep {
  std::size_t state;
  std::size_t equation;
  GiNaC::ex value;
  // When the step inverted a square root (triangular forms only): root_atom = sqrt(a x + b) in
  // x, root = its value w; value = (w^2 - b) / a holds on the branch w >= 0. 0 otherwise.
  GiNaC::ex root_atom = 0;
  GiNaC::ex root = 0;
};

struct CanonicalForm {
  bool applicable = false;     // generic rank n
  std::string not_applicable;  // why not, when !applicable
  // Block sizes k_1..k_p (the observability indices, sum n; {n} for one output). The frame, z,
  // T and l are ordered block by block: (tau_{1,1}..tau_{1,k_1}, tau_{2,1}, ...).
  std::vector<std::size_t> blocks;
  std::string frame_note;    // what the frame's choice leaves open (unequal indices), else empty
  ExVec r;                   // r = tau_1 (one output); r_i = frame[block_start(i)] in general
  std::vector<ExVec> frame;  // tau_1 .. tau_n
  std::vector<BracketCheck> drift;  // [tau_i, tau_j], 1 <= i < j <= n   (C2)
  std::vector<BracketCheck> input;  // [g, tau_j], j not a block end     (C3)
  // C5 <dh_l, tau_j> = delta (i = l the output, 1-based; j the frame index): checked when p > 1
  // and the indices differ; residual = <dh_l, tau_j> - delta.
  std::vector<BracketCheck> output;
  Completeness complete = Completeness::unknown;  // C4
  std::string complete_reason;
  bool linearizable = false;  // C1, C2, C3 not refuted (proved, or only numerically zero)

  std::vector<GiNaC::symbol> y;  // output symbols of l(u, y): y (p = 1) or y1..yp
  std::vector<GiNaC::symbol> z;  // canonical coordinates z1..zn
  ExVec base_point;              // x0 with T(x0) = 0
  Availability T_kind = Availability::none;
  ExVec T;
  std::string T_note;
  ZeroVerdict T_verdict = ZeroVerdict::nonzero;  // dT/dx * [tau] == I
  Availability T_inverse_kind = Availability::none;
  // T^-1 as an elimination sequence (symbolic kind): what reports, JSON and emitters use.
  std::vector<EliminationStep> T_inverse_steps;
  // The composition of the steps, in z1..zn, by substitution only: GiNaC shares its subtrees,
  // but as a tree it can be exponential in n (the nested chain family). Consume it only
  // through the emitter's DAG; never print, expand, normal() or walk it as a tree.
  // Caution: GiNaC's power::eval pulls the content out of a power of a sum
  // ((-z + w^2/2)^2 -> 1/4 (-2 z + w^2)^2); along nested squares these exact factors compound
  // to 2^(+-2^k), which leave the double range at depth 11 (nested chain n >= 11: inf/NaN
  // in double). Straight-line code from T_inverse_steps has no such factors.
  ExVec T_inverse;
  std::string T_inverse_note;
  ZeroVerdict T_inverse_verdict = ZeroVerdict::nonzero;  // every step in its own equation
  Availability l_kind = Availability::none;
  ExVec l;  // in inputs and y
  std::string l_note;
  ZeroVerdict l_verdict = ZeroVerdict::nonzero;  // l free of x

  std::size_t outputs() const { return blocks.size(); }
  std::size_t block_start(std::size_t i) const;  // frame index of tau_{i,1} (0-based i)
  std::size_t block_end(std::size_t i) const;    // frame index of tau_{i,k_i}: z of output i
  std::size_t block_of(std::size_t k) const;     // the output whose block holds frame index k
  bool is_block_end(std::size_t k) const { return k == block_end(block_of(k)); }
  // "tau_3" (one output) or "tau_{2,1}" for frame index k (0-based); likewise for z.
  std::string tau_name(std::size_t k) const;
  std::string z_name(std::size_t k) const { return z[k].get_name(); }
};

struct CanonicalOptions {
  ZeroTestOptions zero;
  // One output whose conditions fail: search y~ = psi(y) that makes them hold
  // (analysis/output_transformation.hpp). Off: the form of y itself, failing.
  bool output_transformation = true;
};

// progress, when given, receives the results as they are found (so a caller that catches a
// budget stop keeps those of the completed stages); the return value is a copy of it.
CanonicalForm analyse_canonical(const Model& m, const Observability& ob, Budget& budget,
                                const CanonicalOptions& opt = {},
                                CanonicalForm* progress = nullptr);

// The frame [tau_1 ... tau_n] as a flat column-major list (tau_1 first).
ExVec frame_column_major(const CanonicalForm& cf);

// Classifies completeness of a vector field: affine or globally Lipschitz => complete
// (conditions.cpp).
Completeness classify_completeness(const ExVec& v, const Symbols& x, std::string& reason);

}  // namespace obsynth
