// Internal to synth/certify: GiNaC expressions compiled once into a straight-line tape
// (shared subexpressions evaluated once), evaluated on Arb balls (rigorous, outward rounded)
// or on doubles (sampling, worst points).
#pragma once

#include <arb.h>
#include <ginac/ginac.h>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "symbolic/dag.hpp"

namespace obsynth::certify::detail {

inline constexpr slong kPrec = 64;  // bits; box widths are far wider than 2^-64

// A vector of Arb balls (RAII).
class BallVec {
 public:
  explicit BallVec(std::size_t n = 0)
      : n_(n), v_(n ? _arb_vec_init(static_cast<slong>(n)) : nullptr) {}
  BallVec(const BallVec&) = delete;
  BallVec& operator=(const BallVec&) = delete;
  BallVec(BallVec&& o) noexcept : n_(o.n_), v_(o.v_) {
    o.n_ = 0;
    o.v_ = nullptr;
  }
  BallVec& operator=(BallVec&& o) noexcept {
    std::swap(n_, o.n_);
    std::swap(v_, o.v_);
    return *this;
  }
  ~BallVec() {
    if (v_) _arb_vec_clear(v_, static_cast<slong>(n_));
  }
  arb_ptr operator[](std::size_t i) { return v_ + i; }
  arb_srcptr operator[](std::size_t i) const { return v_ + i; }
  std::size_t size() const { return n_; }

 private:
  std::size_t n_;
  arb_ptr v_;
};

class Tape {
 public:
  // Throws std::invalid_argument for a symbol that is not in `vars`. `supported()` is false
  // (with `why()`) when an operation cannot be evaluated in balls.
  Tape(const std::vector<GiNaC::ex>& outputs, const std::vector<GiNaC::symbol>& vars);

  bool supported() const { return why_.empty(); }
  const std::string& why() const { return why_; }
  std::size_t num_outputs() const { return outputs_.size(); }
  std::size_t num_vars() const { return nvars_; }
  // Which variables the outputs depend on (bisection splits only these).
  std::vector<bool> used_vars() const {
    std::vector<bool> u(nvars_, false);
    for (const auto& n : nodes_)
      if (n.op == Op::var) u[static_cast<std::size_t>(n.var)] = true;
    return u;
  }

  // Balls of the outputs for the box [lo_i, hi_i]; false if any output is not finite (a pole,
  // a branch cut, log or sqrt of a ball reaching below zero).
  bool eval_box(const std::vector<double>& lo, const std::vector<double>& hi, BallVec& out);
  // Balls of the outputs at an exact double point (radius from the arithmetic only).
  bool eval_point(const std::vector<double>& x, BallVec& out);
  // Whether the last ball evaluation clipped a negative part off a rational power's argument
  // (natural-domain semantics): the mean-value form is not used on such boxes.
  bool clamped() const { return clamped_; }
  std::size_t size() const { return nodes_.size(); }
  // Double evaluation (NaN where undefined).
  void eval_double(const std::vector<double>& x, std::vector<double>& out) const;

  enum class Op {
    var,
    cst,
    add,
    mul,
    powi,
    powq,
    powgen,
    sin,
    cos,
    tan,
    exp,
    log,
    tanh,
    atan,
    abs
  };
  struct Node {
    Op op;
    std::vector<int> args;
    long var = 0;       // var index / integer exponent
    long p = 0, q = 1;  // rational exponent p/q
    double dval = 0;    // constant (double, for eval_double)
  };

 private:
  int lower(const Dag& dag, int id, const std::vector<GiNaC::symbol>& vars, std::vector<int>& done);
  bool run(BallVec& out);
  void init_balls();

  std::vector<Node> nodes_;
  std::vector<int> outputs_;
  std::size_t nvars_;
  std::string why_;
  bool clamped_ = false;
  bool balls_ready_ = false;
  BallVec consts_;  // ball value of constant nodes (indexed like nodes_)
  BallVec work_;
  std::vector<GiNaC::numeric> constants_;  // the value of each cst node (indexed like nodes_)
};

// Upper bound (rounded up) and lower bound (rounded down) of a ball as doubles.
double upper(arb_srcptr x);
double lower(arb_srcptr x);
double abs_upper(arb_srcptr x);
// A rational rounded down / up to a double.
double rational_lower(const GiNaC::numeric& v);
double rational_upper(const GiNaC::numeric& v);

}  // namespace obsynth::certify::detail
