// pipeline_fuzz: grammar-based fuzzer of the whole obsynth pipeline (issue 20, item 2).
//
// From a seed it generates random valid .sym models (an AST, printed), runs on each the
// commands a user runs (check, check --certify, the main job in C++ and C, a compile of every
// emitted header under the generated-code contract flags, a short simulate), each under a
// wall-clock budget, and minimises every finding on the AST. fuzz/README.md has the details.
//
// Standard library + POSIX only: it builds with a plain g++, without GiNaC or clang, and never
// links obsynth: it runs the binary given by --obsynth (Release or ASan + UBSan).

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

// A double as a .sym literal: %g without '+' or leading zeros in the exponent (1e+20 -> 1e20).
std::string literal(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  std::string s = buf;
  const auto e = s.find('e');
  if (e == std::string::npos) return s;
  std::string mant = s.substr(0, e), expo = s.substr(e + 1);
  const bool neg = expo[0] == '-';
  if (expo[0] == '-' || expo[0] == '+') expo.erase(0, 1);
  while (expo.size() > 1 && expo[0] == '0') expo.erase(0, 1);
  return mant + "e" + (neg ? "-" : "") + expo;
}

std::string read_file(const fs::path& p, std::size_t cap = 16u << 20) {
  std::ifstream in(p, std::ios::binary);
  std::string s;
  if (!in) return s;
  s.resize(cap);
  in.read(&s[0], static_cast<std::streamsize>(cap));
  s.resize(static_cast<std::size_t>(in.gcount()));
  return s;
}

void write_file(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}

// The files of a directory with that extension, sorted (none if it does not exist).
std::vector<fs::path> files_with(const fs::path& dir, const std::string& ext) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ext) out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

std::uint64_t fnv1a(const std::string& s) {
  std::uint64_t h = 1469598103934665603ull;
  for (char c : s) h = (h ^ static_cast<unsigned char>(c)) * 1099511628211ull;
  return h;
}

std::string hex8(std::uint64_t h) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%08llx", static_cast<unsigned long long>(h & 0xffffffffull));
  return buf;
}

// The first `lines` lines of a text, for reports and finding headers.
std::string head_lines(const std::string& s, int lines) {
  std::size_t pos = 0;
  for (int k = 0; k < lines && pos != std::string::npos; ++k) {
    pos = s.find('\n', pos);
    if (pos != std::string::npos) ++pos;
  }
  return pos == std::string::npos ? s : s.substr(0, pos);
}

// ---- random numbers ---------------------------------------------------------------------
// Only the engine's raw output is used: the standard distributions are implementation-defined,
// and a seed must give byte-identical models everywhere.
class Rng {
 public:
  Rng(std::uint64_t seed, std::uint64_t index) {
    std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                      static_cast<std::uint32_t>(index), static_cast<std::uint32_t>(index >> 32)};
    eng_.seed(seq);
  }
  int range(int lo, int hi) {
    return lo + static_cast<int>(eng_() % static_cast<std::uint64_t>(hi - lo + 1));
  }
  double unit() { return static_cast<double>(eng_() >> 11) * 0x1.0p-53; }
  bool chance(double p) { return unit() < p; }
  template <class T>
  const T& pick(const std::vector<T>& v) {
    return v[eng_() % v.size()];
  }
  // Index drawn with the given weights.
  int weighted(const std::vector<int>& w) {
    int total = 0;
    for (int x : w) total += x;
    int r = range(0, total - 1);
    for (std::size_t k = 0; k < w.size(); ++k) {
      if (r < w[k]) return static_cast<int>(k);
      r -= w[k];
    }
    return 0;
  }

 private:
  std::mt19937_64 eng_;
};

// ---- model AST --------------------------------------------------------------------------
struct Node {
  enum Kind { num, sym, add, sub, mul, div, pow, neg, call } kind = num;
  std::string text;  // literal, symbol or function name
  std::vector<Node> kids;
};

Node num(const std::string& t) {
  return {Node::num, t, {}};
}
Node sym(const std::string& t) {
  return {Node::sym, t, {}};
}
Node bin(Node::Kind k, Node a, Node b) {
  return {k, "", {std::move(a), std::move(b)}};
}
Node neg(Node a) {
  return {Node::neg, "", {std::move(a)}};
}
Node call(const std::string& fn, Node a) {
  return {Node::call, fn, {std::move(a)}};
}
Node one_plus_square(const std::string& v) {
  return bin(Node::add, num("1"), bin(Node::pow, sym(v), num("2")));
}

int precedence(const Node& e) {
  switch (e.kind) {
    case Node::add:
    case Node::sub:
      return 1;
    case Node::mul:
    case Node::div:
      return 2;
    case Node::neg:
      return 3;
    case Node::pow:
      return 4;
    default:
      return 5;
  }
}

std::string print(const Node& e);

std::string wrap(const Node& e, bool parens) {
  return parens ? "(" + print(e) + ")" : print(e);
}

// Operands of a binary operator: a negation is always bracketed (`a * (-b)`), and the right
// operand of - * / also at equal precedence, so that the printed text parses to the same tree.
std::string operand(const Node& e, int min_prec, bool right) {
  const int p = precedence(e);
  return wrap(e, e.kind == Node::neg || p < min_prec || (right && p == min_prec));
}

std::string print_power(const Node& e) {
  const Node& ex = e.kids[1];
  const bool plain =
      ex.kind == Node::num && ex.text.find_first_not_of("0123456789") == std::string::npos;
  return wrap(e.kids[0], precedence(e.kids[0]) < 5) + "^" + wrap(ex, !plain);
}

std::string print(const Node& e) {
  switch (e.kind) {
    case Node::num:
    case Node::sym:
      return e.text;
    case Node::call:
      return e.text + "(" + print(e.kids[0]) + ")";
    case Node::neg:
      return "-" + wrap(e.kids[0], precedence(e.kids[0]) <= 3);
    case Node::add:
      return operand(e.kids[0], 1, false) + " + " + operand(e.kids[1], 1, false);
    case Node::sub:
      return operand(e.kids[0], 1, false) + " - " + operand(e.kids[1], 1, true);
    case Node::mul:
      return operand(e.kids[0], 2, false) + "*" + operand(e.kids[1], 2, true);
    case Node::div:
      return operand(e.kids[0], 2, false) + "/" + operand(e.kids[1], 2, true);
    case Node::pow:
      return print_power(e);
  }
  return "?";
}

using Terms = std::vector<Node>;  // a component: the sum of its terms (none: 0)

struct Box {
  std::string name;
  double lo, hi;
};

struct Param {
  std::string name;
  std::optional<std::string> value;  // a literal; none: free (then it has a box)
};

struct Model {
  std::string name;
  std::vector<std::string> states, inputs;
  std::vector<Param> params;
  std::vector<Terms> f, g, h;
  bool has_g = false;
  bool whole_field = false;  // printed as F = f + g
  std::vector<std::pair<std::string, double>> nominal;
  bool has_domain = true;
  std::vector<Box> domain;
  std::string c_precision = "double";  // a run setting, kept through minimisation
};

std::string print_component(const Terms& terms) {
  if (terms.empty()) return "0";
  std::string s;
  for (std::size_t k = 0; k < terms.size(); ++k) {
    const Node& t = terms[k];
    if (k == 0) {
      s = print(t);
    } else if (t.kind == Node::neg) {
      s += " - " + operand(t.kids[0], 1, true);
    } else {
      s += " + " + print(t);
    }
  }
  return s;
}

Terms sum_terms(const Terms& a, const Terms& b) {
  Terms s = a;
  s.insert(s.end(), b.begin(), b.end());
  return s;
}

std::string print_field(const std::string& key, const std::vector<Terms>& comps) {
  std::string s = key + " = [ ";
  const std::string indent(key.size() + 5, ' ');
  for (std::size_t i = 0; i < comps.size(); ++i)
    s += (i ? ",\n" + indent : "") + print_component(comps[i]);
  return s + " ]\n";
}

std::string join(const std::vector<std::string>& v, const std::string& sep) {
  std::string s;
  for (std::size_t k = 0; k < v.size(); ++k) s += (k ? sep : "") + v[k];
  return s;
}

std::string print_decls(const Model& m) {
  std::string s = "model " + m.name + "\nstates " + join(m.states, " ") + "\n";
  if (!m.inputs.empty()) s += "inputs " + join(m.inputs, " ") + "\n";
  std::vector<std::string> ps;
  for (const auto& p : m.params) ps.push_back(p.value ? p.name + " = " + *p.value : p.name);
  if (!ps.empty()) s += "params " + join(ps, ", ") + "\n";
  std::vector<std::string> nom;
  for (const auto& [u, v] : m.nominal) nom.push_back(u + " = " + literal(v));
  if (!nom.empty()) s += "nominal " + join(nom, ", ") + "\n";
  return s;
}

std::string print_model(const Model& m) {
  std::string s = print_decls(m);
  if (m.whole_field) {
    std::vector<Terms> F;
    for (std::size_t i = 0; i < m.f.size(); ++i) F.push_back(sum_terms(m.f[i], m.g[i]));
    s += print_field("F", F);
  } else {
    s += print_field("f", m.f);
    if (m.has_g) s += print_field("g", m.g);
  }
  s += print_field("h", m.h);
  std::vector<std::string> boxes;
  for (const auto& b : m.domain)
    boxes.push_back(b.name + " in [" + literal(b.lo) + ", " + literal(b.hi) + "]");
  if (m.has_domain && !boxes.empty()) s += "domain " + join(boxes, ",\n       ") + "\n";
  return s;
}

const Box* find_box(const Model& m, const std::string& name) {
  if (!m.has_domain) return nullptr;
  for (const auto& b : m.domain)
    if (b.name == name) return &b;
  return nullptr;
}

// ---- generator --------------------------------------------------------------------------
struct Var {
  std::string name;
  double lo, hi;
};

const std::vector<std::pair<double, double>> kStateBoxes = {
    {-1, 1},   {-2, 2},    {0.5, 2},    {0, 1}, {-3.2, 3.2}, {1, 10},
    {-10, -1}, {0.1, 0.5}, {-0.5, 0.5}, {0, 5}, {2, 4}};
const std::vector<std::pair<double, double>> kExtremeBoxes = {
    {-1e-3, 1e-3}, {1e5, 1e6}, {-1e20, 1e20}, {1e-8, 1e-6}, {-1e-200, 1e-200}};
const std::vector<std::pair<double, double>> kInputBoxes = {{-1, 1}, {0, 2}, {-2, 2}, {0.5, 1.5}};
const std::vector<std::pair<double, double>> kParamBoxes = {{0.5, 2}, {0.1, 0.5}, {1, 3}, {-1, 1}};
const std::vector<std::string> kOrdinary = {"0.5", "2",    "10", "3",    "1.5", "0.1",
                                            "4",   "0.25", "7",  "0.01", "5",   "1.2"};
// Names the engineer may write that collide with obsynth's, C/C++'s or the C library's own.
const std::vector<std::string> kHostileNames = {
    "n",     "m",      "p",       "y",    "t",     "z1",       "D",   "I",      "Pi",     "E",
    "int",   "double", "class",   "NAN",  "errno", "restrict", "new", "signed", "Scalar", "state",
    "input", "std",    "obsynth", "M_PI", "EOF",   "assert",   "x_1", "min",    "gamma"};
const std::vector<std::string> kTrig = {"sin", "cos", "tanh", "atan"};
const std::vector<std::string> kPlainNames = {"theta", "omega", "v",     "S",  "q",
                                              "soc",   "T",     "alpha", "w2", "X"};

class Generator {
 public:
  Generator(std::uint64_t seed, std::uint64_t index) : r_(seed, index), index_(index) {}
  Model generate();

 private:
  Rng r_;
  std::uint64_t index_;
  Model m_;
  bool clean_ = true;  // singularities kept out of the domain box (else: anywhere)
  std::vector<Var> states_, inputs_;
  std::vector<std::string> param_names_;
  std::set<std::string> used_;

  std::string fresh_name(const std::string& preferred);
  void make_symbols(int n, int m);
  void make_params();
  Var make_var(const std::string& name, const std::vector<std::pair<double, double>>& boxes,
               double extreme);
  Node coef();
  Node extreme();
  Node exponent(bool rational, bool negative);
  Node shifted(const Var& v);
  Node term(const std::vector<Var>& vars, int depth);
  Node leaf_term(const std::vector<Var>& vars, int kind);
  Node function_term(const std::vector<Var>& vars, int depth, int kind);
  Terms component(const std::vector<Var>& vars, int max_terms);
  void make_chain_f();
  void make_random_f();
  void make_g();
  void make_h(int p);
  void make_domain();
};

std::string Generator::fresh_name(const std::string& preferred) {
  std::string name = preferred;
  for (int k = 2; used_.count(name); ++k) name = preferred + "_" + std::to_string(k);
  used_.insert(name);
  return name;
}

Var Generator::make_var(const std::string& name,
                        const std::vector<std::pair<double, double>>& boxes, double extreme) {
  const auto& b = r_.chance(extreme) ? r_.pick(kExtremeBoxes) : r_.pick(boxes);
  return {fresh_name(name), b.first, b.second};
}

void Generator::make_symbols(int n, int m) {
  const bool plain = r_.chance(0.75);
  const int hostile = r_.chance(0.12) ? r_.range(0, n - 1) : -1;
  for (int i = 0; i < n; ++i) {
    std::string name = "x" + std::to_string(i + 1);
    if (i == hostile) {
      name = r_.pick(kHostileNames);
    } else if (!plain) {
      name = r_.pick(kPlainNames);
    }
    states_.push_back(make_var(name, kStateBoxes, 0.03));
  }
  const std::vector<std::string> alt = {"I", "w", "v_in", "torque", "i", "u"};
  for (int j = 0; j < m; ++j) {
    std::string name = m == 1 ? "u" : "u" + std::to_string(j + 1);
    if (r_.chance(0.15)) name = r_.pick(alt);
    inputs_.push_back(make_var(name, kInputBoxes, 0.0));
  }
}

void Generator::make_params() {
  const std::vector<std::string> names = {"a", "b", "k", "c", "mu", "J", "mgl", "beta_", "lambda"};
  const int count = r_.weighted({6, 3, 2});
  for (int k = 0; k < count; ++k) {
    Param p{fresh_name(r_.pick(names)), std::nullopt};
    if (r_.chance(0.5)) {
      p.value = r_.pick(kOrdinary);
    } else {
      const auto& b = r_.pick(kParamBoxes);
      m_.domain.push_back({p.name, b.first, b.second});
    }
    param_names_.push_back(p.name);
    m_.params.push_back(p);
  }
}

// Mostly ordinary magnitudes; sometimes a rational, a parameter or an extreme literal.
Node Generator::coef() {
  if (r_.chance(0.015)) return extreme();
  if (!param_names_.empty() && r_.chance(0.2)) return sym(r_.pick(param_names_));
  if (r_.chance(0.12)) {
    const int a = r_.range(1, 9);  // every draw in its own statement: argument evaluation
    const int b = r_.range(2, 9);  // order is unspecified, the models must not depend on it
    return bin(Node::div, num(std::to_string(a)), num(std::to_string(b)));
  }
  return num(r_.pick(kOrdinary));
}

Node Generator::extreme() {
  const int e = r_.range(20, 300);
  std::string mant = std::to_string(r_.range(1, 9));
  if (r_.chance(0.3)) mant += ".5";
  return num(mant + "e" + (r_.chance(0.5) ? "-" : "") + std::to_string(e));
}

Node Generator::exponent(bool rational, bool negative) {
  if (!rational) {
    const int k = r_.pick(negative ? std::vector<int>{2, 3, 2, 4, 5, -1, -2}
                                   : std::vector<int>{2, 3, 2, 4, 5});
    return k < 0 ? neg(num(std::to_string(-k))) : num(std::to_string(k));
  }
  const std::vector<std::pair<int, int>> q = {{1, 2}, {3, 2}, {1, 3}, {-1, 2}, {2, 3}, {5, 2}};
  const auto& [a, b] = r_.pick(q);
  Node frac = bin(Node::div, num(std::to_string(std::abs(a))), num(std::to_string(b)));
  return a < 0 ? neg(frac) : frac;
}

// v - c: positive over v's box, crossing zero inside it, or negative over it (singularities of
// 1/., log, sqrt and rational powers inside or outside the domain).
Node Generator::shifted(const Var& v) {
  const double width = v.hi - v.lo;
  double c = 0;
  switch (clean_ ? 0 : r_.weighted({5, 3, 2})) {
    case 0:
      c = v.lo - r_.pick(std::vector<double>{0.5, 1, 2, 0.1 * width});
      break;
    case 1:  // the pole at 0 itself (1/x1 on [-1, 1]) half the time it is in the box
      c = v.lo < 0 && v.hi > 0 && r_.chance(0.5)
              ? 0
              : v.lo + width * r_.pick(std::vector<double>{0.5, 0.25, 0.75});
      break;
    default:
      c = v.hi + r_.pick(std::vector<double>{0.5, 1, 0.1 * width});
  }
  if (c == 0) return sym(v.name);
  return c > 0 ? bin(Node::sub, sym(v.name), num(literal(c)))
               : bin(Node::add, sym(v.name), num(literal(-c)));
}

Node Generator::leaf_term(const std::vector<Var>& vars, int kind) {
  const Var& v = r_.pick(vars);
  const Node x = sym(v.name);
  switch (kind) {
    case 0:  // c*v^k, v, v*w
      if (r_.chance(0.3)) return bin(Node::mul, coef(), x);
      if (r_.chance(0.3)) return bin(Node::mul, x, sym(r_.pick(vars).name));
      {
        const Node c = coef();
        const bool pole = v.lo <= 0 && v.hi >= 0;
        return bin(Node::mul, c, bin(Node::pow, x, exponent(false, !clean_ || !pole)));
      }
    case 1:  // rational
      if (r_.chance(0.3)) return bin(Node::div, x, one_plus_square(r_.pick(vars).name));
      {
        const Node c = coef();
        return bin(Node::div, c, shifted(v));
      }
    case 2:  // power of a sum, rational exponent
      if (r_.chance(0.4)) {
        const Node base = bin(Node::add, x, coef());
        return bin(Node::pow, base, exponent(false, !clean_));
      }
      {
        const Node base = shifted(v);
        return bin(Node::pow, base, exponent(true, true));
      }
    default:
      return x;
  }
}

Node Generator::function_term(const std::vector<Var>& vars, int depth, int kind) {
  const Var& v = r_.pick(vars);
  const Node arg = depth < 2 && r_.chance(0.3) ? term(vars, depth + 1) : sym(v.name);
  switch (kind) {
    case 0:
      if (r_.chance(0.2)) return call("exp", neg(bin(Node::pow, sym(v.name), num("2"))));
      return call("exp", bin(Node::mul, coef(), arg));
    case 1:
      return call("log", shifted(v));
    case 2:
      return call("sqrt", shifted(v));
    case 3: {
      const Node c = coef();
      return bin(Node::mul, c, call(r_.pick(kTrig), arg));
    }
    default:
      if (!clean_) return call("tan", arg);
      return call(v.lo > -1.2 && v.hi < 1.2 ? "tan" : "tanh", sym(v.name));
  }
}

// A term of bounded depth: polynomial, rational, power, elementary function, or a product,
// sum, quotient or negation of smaller terms.
Node Generator::term(const std::vector<Var>& vars, int depth) {
  const bool deep = depth < 2;
  const int kind = r_.weighted({30, clean_ ? 12 : 24, 8, 6, 6, 6, 12, 3, deep ? 8 : 0, deep ? 3 : 0,
                                deep ? 2 : 0, 4});  // more quotients where poles may sit in the box
  if (kind <= 2) return leaf_term(vars, kind);
  if (kind <= 7) return function_term(vars, depth, kind - 3);
  if (kind == 11) return neg(leaf_term(vars, r_.range(0, 2)));
  const Node a = term(vars, depth + 1);
  if (kind == 8) return bin(Node::mul, a, term(vars, depth + 1));
  if (kind == 9) return bin(Node::add, a, term(vars, depth + 1));
  return bin(Node::div, a, one_plus_square(r_.pick(vars).name));
}

Terms Generator::component(const std::vector<Var>& vars, int max_terms) {
  Terms t;
  const int count = std::min(max_terms, 1 + r_.weighted({50, 35, 15}));
  for (int k = 0; k < count; ++k) t.push_back(term(vars, 0));
  return t;
}

// x_{k+1} in f_k along a chain (in order or permuted), lower-triangular extras, everything in
// the last component: observable from h = x_first for most coefficients.
void Generator::make_chain_f() {
  const int n = static_cast<int>(states_.size());
  std::vector<int> order(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) order[static_cast<std::size_t>(i)] = i;
  if (r_.chance(0.2))
    for (int i = n - 1; i > 0; --i)
      std::swap(order[static_cast<std::size_t>(i)],
                order[static_cast<std::size_t>(r_.range(0, i))]);
  m_.f.assign(static_cast<std::size_t>(n), {});
  std::vector<Var> seen;
  for (int k = 0; k < n; ++k) {
    const Var& cur = states_[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])];
    seen.push_back(cur);
    Terms& fk = m_.f[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])];
    if (k + 1 == n) {
      fk = component(states_, 3);
      continue;
    }
    Node next = sym(states_[static_cast<std::size_t>(order[static_cast<std::size_t>(k + 1)])].name);
    if (r_.chance(0.25)) next = bin(Node::mul, coef(), next);
    fk.push_back(next);
    if (r_.chance(0.5)) fk.push_back(term(seen, 0));
  }
}

void Generator::make_random_f() {
  const std::size_t n = states_.size();
  for (std::size_t i = 0; i < n; ++i) {
    Terms t = component(states_, 3);
    if (r_.chance(0.5)) t.push_back(bin(Node::mul, coef(), sym(states_[(i + 1) % n].name)));
    m_.f.push_back(t);
  }
}

// g vanishes at u = 0: every term carries a factor u, u^2, sin(u) or tanh(u).
void Generator::make_g() {
  m_.g.assign(states_.size(), {});
  if (inputs_.empty() || r_.chance(0.15)) return;
  m_.has_g = true;
  for (auto& gi : m_.g) {
    if (r_.chance(0.4)) continue;
    const Node u = sym(r_.pick(inputs_).name);
    Node factor = u;
    const int k = r_.weighted({8, 1, 1, 1});
    if (k == 1) factor = bin(Node::pow, u, num("2"));
    if (k == 2) factor = call("sin", u);
    if (k == 3) factor = call("tanh", u);
    gi.push_back(r_.chance(0.4) ? bin(Node::mul, coef(), factor)
                                : bin(Node::mul, term(states_, 1), factor));
  }
  m_.whole_field = r_.chance(0.1);
  if (m_.whole_field && r_.chance(0.5))
    for (const auto& u : inputs_) m_.nominal.push_back({u.name, (u.lo + u.hi) / 2});
}

// y1 = the chain's head (plus a term in it) in most models; feedthrough sometimes.
void Generator::make_h(int p) {
  const Var& head = states_[0];
  Terms h1{sym(head.name)};
  const int shape = r_.weighted({6, 2, 2});
  if (shape == 1) h1.push_back(term({head}, 1));
  if (shape == 2) h1 = {term({head}, 1)};
  if (!inputs_.empty() && r_.chance(0.15)) {
    const Node u = sym(r_.pick(inputs_).name);
    h1.push_back(r_.chance(0.7) ? bin(Node::mul, coef(), u) : bin(Node::mul, sym(head.name), u));
  }
  m_.h.push_back(h1);
  for (int k = 1; k < p; ++k) {
    const Var& v = r_.pick(states_);
    m_.h.push_back(r_.chance(0.5) ? Terms{sym(v.name)} : Terms{term({v}, 1)});
  }
}

void Generator::make_domain() {
  const int shape = r_.weighted({92, 4, 4});
  m_.has_domain = shape != 1;
  std::vector<Box> boxes;
  for (const auto& v : states_)
    if (shape != 2 || r_.chance(0.5)) boxes.push_back({v.name, v.lo, v.hi});
  for (const auto& u : inputs_) boxes.push_back({u.name, u.lo, u.hi});
  m_.domain.insert(m_.domain.begin(), boxes.begin(), boxes.end());
}

Model Generator::generate() {
  const int n = 1 + r_.weighted({10, 30, 25, 15, 8, 5, 4, 3});
  const int m = r_.weighted({35, 45, 20});
  const int p = std::min(n, 1 + r_.weighted({60, 30, 10}));
  clean_ = r_.chance(0.6);
  m_.name = "pf" + std::to_string(index_);
  if (r_.chance(0.03))
    m_.name = r_.pick(std::vector<std::string>{"Model", "std", "obsynth", "x1", "int_"});
  make_symbols(n, m);
  for (const auto& v : states_) m_.states.push_back(v.name);
  for (const auto& u : inputs_) m_.inputs.push_back(u.name);
  make_params();
  if (r_.chance(0.65)) {
    make_chain_f();
  } else {
    make_random_f();
  }
  make_g();
  make_h(p);
  make_domain();
  m_.c_precision = r_.chance(0.5) ? "float" : "double";
  return m_;
}

// ---- output checks ----------------------------------------------------------------------
// Strict RFC 8259 validation: NaN, Infinity, trailing commas and bare words are all invalid.
class JsonCheck {
 public:
  explicit JsonCheck(const std::string& s) : s_(s) {}
  bool valid() {
    ws();
    if (!value(0)) return false;
    ws();
    return i_ == s_.size();
  }

 private:
  const std::string& s_;
  std::size_t i_ = 0;

  bool at(char c) const { return i_ < s_.size() && s_[i_] == c; }
  void ws() {
    while (i_ < s_.size() && std::strchr(" \t\r\n", s_[i_]) && s_[i_]) ++i_;
  }
  bool eat(char c) {
    ws();
    if (!at(c)) return false;
    ++i_;
    return true;
  }
  bool value(int depth) {
    ws();
    if (depth > 512 || i_ >= s_.size()) return false;
    const char c = s_[i_];
    if (c == '{') return object(depth);
    if (c == '[') return array(depth);
    if (c == '"') return string();
    if (c == '-' || std::isdigit(static_cast<unsigned char>(c))) return number();
    return word("true") || word("false") || word("null");
  }
  bool word(const char* w) {
    const std::size_t len = std::strlen(w);
    if (s_.compare(i_, len, w) != 0) return false;
    i_ += len;
    return true;
  }
  bool digits() {
    const std::size_t start = i_;
    while (i_ < s_.size() && std::isdigit(static_cast<unsigned char>(s_[i_]))) ++i_;
    return i_ > start;
  }
  bool number() {
    if (at('-')) ++i_;
    if (at('0')) {
      ++i_;
    } else if (!digits()) {
      return false;
    }
    if (at('.') && (++i_, !digits())) return false;
    if (at('e') || at('E')) {
      ++i_;
      if (at('+') || at('-')) ++i_;
      if (!digits()) return false;
    }
    return true;
  }
  bool string() {
    ++i_;
    while (i_ < s_.size() && s_[i_] != '"') {
      const unsigned char c = static_cast<unsigned char>(s_[i_]);
      if (c < 0x20) return false;
      if (c == '\\') {
        if (++i_ >= s_.size() || !std::strchr("\"\\/bfnrtu", s_[i_])) return false;
        if (s_[i_] == 'u') {
          for (int k = 0; k < 4; ++k)
            if (++i_ >= s_.size() || !std::isxdigit(static_cast<unsigned char>(s_[i_])))
              return false;
        }
      }
      ++i_;
    }
    if (!at('"')) return false;
    ++i_;
    return true;
  }
  bool array(int depth) {
    ++i_;
    if (eat(']')) return true;
    do {
      if (!value(depth + 1)) return false;
    } while (eat(','));
    return eat(']');
  }
  bool object(int depth) {
    ++i_;
    if (eat('}')) return true;
    do {
      ws();
      if (!at('"') || !string() || !eat(':') || !value(depth + 1)) return false;
    } while (eat(','));
    return eat('}');
  }
};

bool is_word_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
}

bool token_at(const std::string& s, std::size_t p, std::size_t len) {
  const bool before = p == 0 || !is_word_char(s[p - 1]);
  return before && (p + len >= s.size() || !is_word_char(s[p + len]));
}

// A standalone token (nan, -nan, nan(0x..)): printf's and fmt's spelling of a NaN. Prose never
// uses lowercase "nan" as a word; "NaN" is left to the JSON check (the report says "never a
// NaN"). "inf" is printed on purpose by obsynth (an unbounded Lipschitz constant), hence opt-in.
bool has_token(const std::string& s, const std::string& tok) {
  for (auto p = s.find(tok); p != std::string::npos; p = s.find(tok, p + 1))
    if (token_at(s, p, tok.size())) return true;
  return false;
}

// Where the token occurs (at most five places, 120 characters each side): the evidence.
std::string token_lines(const std::string& s, const std::string& tok) {
  std::string out;
  int n = 0;
  for (auto p = s.find(tok); p != std::string::npos && n < 5; p = s.find(tok, p + 1)) {
    if (!token_at(s, p, tok.size())) continue;
    const std::size_t from = p < 120 ? 0 : p - 120;
    std::string window = s.substr(from, p - from + tok.size() + 120);
    std::replace(window.begin(), window.end(), '\n', ' ');
    out += "..." + window + "...\n";
    ++n;
  }
  return out;
}

// The sanitizer report in a stderr, as "<tool>: <error type>", or empty.
std::string sanitizer_report(const std::string& err) {
  for (const char* tool : {"AddressSanitizer", "LeakSanitizer", "UndefinedBehaviorSanitizer",
                           "ThreadSanitizer", "MemorySanitizer"}) {
    const auto p = err.find(std::string(tool) + ":");
    if (p == std::string::npos) continue;
    std::istringstream rest(err.substr(p + std::strlen(tool) + 1));
    std::string type;
    rest >> type;
    return std::string(tool) + ": " + type;
  }
  if (err.find("runtime error:") != std::string::npos)
    return "UndefinedBehaviorSanitizer: runtime error";
  return "";
}

// The first line of a stderr that says "error:", else its first line.
std::string first_error(const std::string& err) {
  std::istringstream in(err);
  std::string line, first;
  while (std::getline(in, line)) {
    if (first.empty()) first = line;
    if (line.find("error:") != std::string::npos) return line.substr(0, 300) + "\n";
  }
  return first.substr(0, 300) + "\n";
}

// What an internal error is about, without the model's expressions or numbers: the first
// "error:" line cut at the first digit, quote, '=' or '(' (it keys the minimiser and the
// deduplication, so that both stay on one bug).
std::string error_class(const std::string& err) {
  std::string line = first_error(err);
  const auto colon = line.find("error:");
  if (colon != std::string::npos) line = line.substr(colon);
  line = line.substr(0, line.find_first_of("0123456789'`\"=(\n"));
  while (!line.empty() && line.back() == ' ') line.pop_back();
  return line;
}

// ---- running commands -------------------------------------------------------------------
struct RunResult {
  int exit_code = -1;  // when the process exited
  int signal = 0;      // when a signal ended it
  bool timed_out = false;
  double seconds = 0;
  std::string out, err;
};

std::vector<char*> c_argv(std::vector<std::string>& args) {
  std::vector<char*> v;
  for (auto& a : args) v.push_back(&a[0]);
  v.push_back(nullptr);
  return v;
}

// Runs argv under `timeout -s KILL limit` (which kills the whole process group: obsynth's forked
// worker too), stdout and stderr to files in `scratch` (no pipes to drain, no deadlock).
RunResult run_once(const std::vector<std::string>& argv, double limit, const fs::path& scratch) {
  std::vector<std::string> full = {"timeout", "-s", "KILL", fixed(limit, 1)};
  full.insert(full.end(), argv.begin(), argv.end());
  const std::string out = (scratch / "stdout").string(), err = (scratch / "stderr").string();
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> cargs = c_argv(full);
  RunResult r;
  const auto t0 = Clock::now();
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, "timeout", &fa, nullptr, cargs.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    std::fprintf(stderr, "pipeline_fuzz: cannot run timeout: %s\n", std::strerror(rc));
    std::exit(2);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  r.seconds = seconds_since(t0);
  if (WIFSIGNALED(status)) {
    r.signal = WTERMSIG(status);
    r.timed_out = r.signal == SIGKILL && r.seconds >= limit - 0.5;
  } else {
    r.exit_code = WEXITSTATUS(status);
  }
  r.out = read_file(out);
  r.err = read_file(err);
  return r;
}

// timeout exits 126/127 when it cannot start the command: the binary is missing or being
// rebuilt (ninja replaces it). That is the harness's problem, not a finding: wait and retry.
RunResult run_command(const std::vector<std::string>& argv, double limit, const fs::path& scratch) {
  for (int attempt = 0;; ++attempt) {
    RunResult r = run_once(argv, limit, scratch);
    const bool not_run = (r.exit_code == 126 || r.exit_code == 127) &&
                         r.err.rfind("timeout: failed to run command", 0) == 0;
    if (!not_run) return r;
    if (attempt == 60) {
      std::fprintf(stderr, "pipeline_fuzz: %s", r.err.c_str());
      std::exit(2);
    }
    std::this_thread::sleep_for(std::chrono::seconds(5));
  }
}

// ---- options ----------------------------------------------------------------------------
struct Options {
  std::uint64_t seed = 1;
  std::uint64_t first_index = 0;
  long models = -1;  // -1: until --seconds (or 20 without it)
  double seconds = 0;
  std::string obsynth = "build/synth/obsynth";
  std::string source_dir = ".";
  std::vector<std::string> eigen_include = {"/usr/include/eigen3"};
  std::string cxx = "g++", cc = "gcc";
  int jobs = 1;
  std::string findings = "fuzz/pipeline-findings";
  std::string work;
  bool keep_going = false, quick = false, minimise = true, flag_inf = false, keep_work = false;
  bool verbose = false;
  double budget = 60;  // seconds per obsynth command (its --total-seconds)
  double minimise_seconds = 600;
  std::string max_memory = "4G";
  std::string dump;                // write the models there and stop
  std::vector<std::string> units;  // --units: only these (default: all, or --quick's)
};

// The contract flags of tests/generated/CMakeLists.txt (OBSYNTH_CONTRACT_FLAGS,
// OBSYNTH_C_STRICT_FLAGS): what generated code promises, nothing more.
const std::vector<std::string> kCxxFlags = {
    "-std=c++17",         "-Wall",     "-Wextra",         "-Werror",   "-Wconversion",
    "-Wdouble-promotion", "-pedantic", "-fno-exceptions", "-fno-rtti", "-fsyntax-only"};
const std::vector<std::string> kCFlags = {"-std=c99",  "-Wall",        "-Wextra",
                                          "-Werror",   "-Wconversion", "-Wdouble-promotion",
                                          "-pedantic", "-fsyntax-only"};

// ---- the pipeline -----------------------------------------------------------------------
struct Step {
  std::string label;
  RunResult run;
};

struct Finding {
  std::string unit, kind, key, command, evidence;
  double seconds = 0;  // of the failing unit's steps
};

struct UnitResult {
  std::vector<Step> steps;
  std::optional<Finding> finding;
};

const std::vector<std::string> kUnits = {"check",       "check-json", "check-certify", "main-auto",
                                         "main-auto-c", "main-all",   "main-all-c",    "simulate"};

bool unit_in_quick(const std::string& u) {
  return u != "check-certify" && u != "main-all" && u != "main-all-c";
}

bool runs_unit(const Options& o, const std::string& u) {
  if (!o.units.empty()) return std::find(o.units.begin(), o.units.end(), u) != o.units.end();
  return !o.quick || unit_in_quick(u);
}

std::string code_text(const RunResult& r) {
  if (r.timed_out) return "KILL(timeout)";
  if (r.signal) return "SIG" + std::to_string(r.signal);
  return std::to_string(r.exit_code);
}

// The command as a shell line, with paths relative to the unit's directory (model.sym, out-*).
std::string command_text(const std::vector<std::string>& argv, const fs::path& dir) {
  const std::string prefix = dir.string() + "/";
  std::string s;
  for (std::string a : argv) {
    for (auto p = a.find(prefix); p != std::string::npos; p = a.find(prefix))
      a.erase(p, prefix.size());
    const bool quote = a.find_first_of(" ,()*") != std::string::npos;
    s += (s.empty() ? "" : " ") + (quote ? "'" + a + "'" : a);
  }
  return s;
}

// The finding, if any, in one obsynth run: the order is that of severity.
std::optional<Finding> classify(const RunResult& r, bool json_out, bool flag_inf) {
  const auto found = [](std::string kind, std::string key, std::string evidence) {
    return std::optional<Finding>(
        Finding{"", std::move(kind), std::move(key), "", std::move(evidence)});
  };
  const std::string san = sanitizer_report(r.err);
  if (r.timed_out) return found("timeout", "", "killed after " + fixed(r.seconds, 1) + " s");
  if (!san.empty()) return found("sanitizer", san, head_lines(r.err, 40));
  if (r.signal) return found("signal", std::to_string(r.signal), head_lines(r.err, 40));
  if (r.exit_code == 2) return found("exit2", error_class(r.err), head_lines(r.err, 20));
  if (r.exit_code != 0 && r.exit_code != 1)
    return found("exit" + std::to_string(r.exit_code), "", head_lines(r.err, 20));
  // Every user error and budget stop is an "error:" line (file:line:col: error:, obsynth: error:).
  if (r.exit_code == 1 && r.err.find("error:") == std::string::npos)
    return found("silent-exit1", "",
                 "exit 1 without an error: line on stderr\n" + head_lines(r.err, 10));
  for (const std::string tok : {"nan", "inf"}) {
    if (tok == "inf" && !flag_inf) continue;
    if (has_token(r.out, tok) || has_token(r.err, tok))
      return found(tok, "", token_lines(r.out + "\n" + r.err, tok));
  }
  const bool expect_json = json_out && (r.exit_code == 0 || !r.out.empty());
  if (expect_json && !JsonCheck(r.out).valid()) return found("bad-json", "", head_lines(r.out, 30));
  return std::nullopt;
}

class Pipeline {
 public:
  // budget: obsynth's --total-seconds (the minimiser gives candidates less than a full run).
  Pipeline(const Options& o, double budget) : o_(o), budget_(budget) {}
  UnitResult run_unit(const std::string& unit, const Model& m, const fs::path& dir) const;

 private:
  const Options& o_;
  double budget_;

  std::vector<std::string> budget_args() const {
    return {"--total-seconds", fixed(budget_, 1), "--max-memory", o_.max_memory};
  }
  double kill_limit() const { return budget_ * 1.5 + 5; }
  std::vector<std::string> unit_args(const std::string& unit, const Model& m, const fs::path& model,
                                     const fs::path& out) const;
  std::vector<std::string> simulate_args(const Model& m) const;
  void obsynth_step(UnitResult& res, const std::string& unit, const std::vector<std::string>& argv,
                    const fs::path& dir) const;
  void check_outputs(UnitResult& res, const Model& m, const fs::path& out, bool c) const;
  void compile(UnitResult& res, const fs::path& out, bool c, const fs::path& dir) const;
  std::vector<std::string> compiler_argv(const fs::path& out, bool c, const fs::path& tu) const;
};

std::vector<std::string> Pipeline::simulate_args(const Model& m) const {
  std::vector<std::string> x0, xh0, u;
  for (const auto& s : m.states) {
    const Box* b = find_box(m, s);
    const double lo = b ? b->lo : -1, hi = b ? b->hi : 1;
    x0.push_back(literal((lo + hi) / 2 + 0.3 * (hi - lo) / 2));
    xh0.push_back(literal((lo + hi) / 2));
  }
  for (const auto& name : m.inputs) {
    const Box* b = find_box(m, name);
    const double lo = b ? b->lo : -1, hi = b ? b->hi : 1;
    u.push_back(literal((lo + hi) / 2) + " + " + literal((hi - lo) / 4) + "*sin(t)");
  }
  std::vector<std::string> a = {"--method", "auto",         "--x0",    join(x0, ","),
                                "--xhat0",  join(xh0, ","), "--t-end", o_.quick ? "0.5" : "2",
                                "--dt",     "0.001"};
  if (!u.empty()) a.insert(a.end(), {"--u", join(u, ",")});
  return a;
}

std::vector<std::string> Pipeline::unit_args(const std::string& unit, const Model& m,
                                             const fs::path& model, const fs::path& out) const {
  std::vector<std::string> a = {o_.obsynth};
  const std::string M = model.string(), D = out.string();
  if (unit == "check") a.insert(a.end(), {"check", M});
  if (unit == "check-json") a.insert(a.end(), {"check", M, "--format", "json", "--no-timings"});
  if (unit == "check-certify") a.insert(a.end(), {"check", M, "--certify", "--format", "json"});
  if (unit.rfind("main-", 0) == 0) {
    const bool all = unit.find("all") != std::string::npos;
    a.insert(a.end(), {M, "-o", D, "--method", all ? "all" : "auto"});
    if (unit.back() == 'c') a.insert(a.end(), {"--language", "c", "--precision", m.c_precision});
  }
  if (unit == "simulate") {
    a.insert(a.end(), {"simulate", M, "-o", D});
    const auto s = simulate_args(m);
    a.insert(a.end(), s.begin(), s.end());
  }
  const auto b = budget_args();
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

void Pipeline::obsynth_step(UnitResult& res, const std::string& unit,
                            const std::vector<std::string>& argv, const fs::path& dir) const {
  RunResult r = run_command(argv, kill_limit(), dir);
  auto f =
      classify(r, unit.find("json") != std::string::npos || unit == "check-certify", o_.flag_inf);
  res.steps.push_back({"", r});
  if (!f) return;
  f->command = command_text(argv, dir);
  res.finding = f;
}

// After a successful main job: headers exist, the reports are valid, then they compile.
void Pipeline::check_outputs(UnitResult& res, const Model& m, const fs::path& out, bool c) const {
  const auto fail = [&](const std::string& kind, const std::string& evidence) {
    res.finding = Finding{"", kind, "", "", evidence};
  };
  const fs::path json = out / (m.name + "_report.json"), md = out / (m.name + "_report.md");
  if (files_with(out, c ? ".h" : ".hpp").empty())
    return fail("no-output", "exit 0 but no header in the output directory");
  if (fs::exists(json) && !JsonCheck(read_file(json)).valid())
    return fail("bad-json", head_lines(read_file(json), 30));
  const std::string report = read_file(md);
  if (has_token(report, "nan")) return fail("nan", "in the report: " + token_lines(report, "nan"));
}

// The first compiler error: its warning flag (-Werror=conversion), else "error".
std::string compile_error_class(const std::string& err) {
  const std::string line = first_error(err);
  const auto w = line.find("[-W");
  return w == std::string::npos ? "error" : line.substr(w + 1, line.find(']', w) - w - 1);
}

// The namespace-scope class templates of one type parameter in a generated header, as
// "struct obsynth_gen::m::CanonicalFunctions". The emitter's layout: `namespace X {` at column 0,
// `template <class Scalar...>` on the line before `class Name {` / `struct Name {`.
std::vector<std::string> class_templates(const std::string& header) {
  std::vector<std::string> out, ns;
  std::istringstream in(header);
  std::string line, prev;
  while (std::getline(in, line)) {
    if (line.rfind("namespace ", 0) == 0 && line.back() == '{')
      ns.push_back(line.substr(10, line.size() - 12));
    if (line.rfind("}  // namespace", 0) == 0 && !ns.empty()) ns.pop_back();
    const bool one_type =
        prev.rfind("template <class Scalar", 0) == 0 && prev.find(',') == std::string::npos;
    for (const std::string kw : {"class ", "struct "}) {
      if (!one_type || line.rfind(kw, 0) != 0 || line.back() != '{') continue;
      std::istringstream words(line.substr(kw.size()));
      std::string name;
      words >> name;
      out.push_back(kw + join(ns, "::") + "::" + name);
    }
    prev = line;
  }
  return out;
}

// One translation unit with every header; in C++ every class template is also instantiated
// for float and double (as tests/generated does): templates never instantiated are barely checked.
std::string translation_unit(const std::vector<fs::path>& headers, bool c) {
  std::string tu, inst;
  std::set<std::string> seen;  // a model's shared block is in every header, defined once
  for (const auto& h : headers) {
    tu += "#include \"" + h.filename().string() + "\"\n";
    if (c) continue;
    for (const auto& t : class_templates(read_file(h))) {
      if (!seen.insert(t).second) continue;
      for (const char* s : {"float", "double"}) inst += "template " + t + "<" + s + ">;\n";
    }
  }
  return tu + inst;
}

std::vector<std::string> Pipeline::compiler_argv(const fs::path& out, bool c,
                                                 const fs::path& tu) const {
  std::vector<std::string> argv = {c ? o_.cc : o_.cxx};
  const auto& flags = c ? kCFlags : kCxxFlags;
  argv.insert(argv.end(), flags.begin(), flags.end());
  argv.insert(argv.end(), {"-I", (fs::path(o_.source_dir) / "runtime").string()});
  for (const auto& inc : o_.eigen_include) argv.insert(argv.end(), {"-I", inc});
  argv.insert(argv.end(), {"-I", out.string(), tu.string()});
  if (c)  // gcc checks each .c in turn
    for (const auto& s : files_with(out, ".c")) argv.push_back(s.string());
  return argv;
}

void Pipeline::compile(UnitResult& res, const fs::path& out, bool c, const fs::path& dir) const {
  const fs::path tu = dir / (c ? "tu.c" : "tu.cpp");
  const std::string text = translation_unit(files_with(out, c ? ".h" : ".hpp"), c);
  write_file(tu, text);
  const auto argv = compiler_argv(out, c, tu);
  RunResult r = run_command(argv, std::max(120.0, 2 * o_.budget), dir);
  res.steps.push_back({"cc", r});
  if (r.exit_code == 0) return;
  const std::string kind = r.timed_out ? "compile-timeout" : c ? "compile-c" : "compile-cpp";
  std::string errors = r.err;
  const std::string prefix = dir.string() + "/";
  for (auto p = errors.find(prefix); p != std::string::npos; p = errors.find(prefix))
    errors.erase(p, prefix.size());
  res.finding = Finding{
      "", kind, compile_error_class(errors), command_text(argv, dir),
      head_lines(errors, 40) + "\ntranslation unit " + tu.filename().string() + ":\n" + text};
}

UnitResult Pipeline::run_unit(const std::string& unit, const Model& m, const fs::path& dir) const {
  UnitResult res;
  fs::create_directories(dir);
  const fs::path model = dir / "model.sym", out = dir / ("out-" + unit);
  write_file(model, print_model(m));
  const auto argv = unit_args(unit, m, model, out);
  obsynth_step(res, unit, argv, dir);
  const RunResult& r = res.steps.back().run;
  const bool main_job = unit.rfind("main-", 0) == 0, c = unit.back() == 'c';
  if (!res.finding && r.exit_code == 0 && main_job) {
    check_outputs(res, m, out, c);
    if (!res.finding) compile(res, out, c, dir);
  }
  if (!res.finding && r.exit_code == 0 && unit == "simulate" && files_with(out, ".csv").empty())
    res.finding = Finding{"", "no-output", "", "", "exit 0 but no CSV"};
  if (res.finding) {
    res.finding->unit = unit;
    for (const auto& step : res.steps) res.finding->seconds += step.run.seconds;
    if (res.finding->command.empty()) res.finding->command = command_text(argv, dir);
  }
  return res;
}

// ---- minimiser --------------------------------------------------------------------------
// Candidates are smaller variants of a model (printed text strictly shorter, so the greedy loop
// ends); a candidate is kept when the failing unit gives a finding of the same kind and key.

void visit(Node& e, const std::function<void(Node&)>& fn) {
  fn(e);
  for (auto& k : e.kids) visit(k, fn);
}

void visit_model(Model& m, const std::function<void(Node&)>& fn) {
  for (auto* field : {&m.f, &m.g, &m.h})
    for (auto& comp : *field)
      for (auto& t : comp) visit(t, fn);
}

void substitute(Model& m, const std::string& name, const Node& by) {
  visit_model(m, [&](Node& e) {
    if (e.kind == Node::sym && e.text == name) e = by;
  });
}

void drop_box(Model& m, const std::string& name) {
  m.domain.erase(std::remove_if(m.domain.begin(), m.domain.end(),
                                [&](const Box& b) { return b.name == name; }),
                 m.domain.end());
}

template <class T>
void erase_at(std::vector<T>& v, std::size_t i) {
  v.erase(v.begin() + static_cast<std::ptrdiff_t>(i));
}

// A state goes with its f and g components and its box; where it is used, 0 or 1 stands in.
void drop_states(const Model& m, std::vector<Model>& out) {
  for (std::size_t i = 0; m.states.size() > 1 && i < m.states.size(); ++i) {
    for (const char* by : {"0", "1"}) {
      Model c = m;
      erase_at(c.states, i);
      erase_at(c.f, i);
      erase_at(c.g, i);
      drop_box(c, m.states[i]);
      substitute(c, m.states[i], num(by));
      out.push_back(c);
    }
  }
}

void drop_inputs(const Model& m, std::vector<Model>& out) {
  for (std::size_t j = 0; j < m.inputs.size(); ++j) {
    Model c = m;
    const std::string u = m.inputs[j];
    erase_at(c.inputs, j);
    drop_box(c, u);
    c.nominal.erase(std::remove_if(c.nominal.begin(), c.nominal.end(),
                                   [&](const auto& nv) { return nv.first == u; }),
                    c.nominal.end());
    if (c.inputs.empty()) c.has_g = c.whole_field = false;
    substitute(c, u, num("0"));  // g still vanishes at u = 0
    out.push_back(c);
  }
}

void drop_params(const Model& m, std::vector<Model>& out) {
  for (std::size_t k = 0; k < m.params.size(); ++k) {
    Model c = m;
    const Param p = m.params[k];
    erase_at(c.params, k);
    drop_box(c, p.name);
    substitute(c, p.name, num(p.value ? *p.value : "1"));
    out.push_back(c);
  }
}

void structural_candidates(const Model& m, std::vector<Model>& out) {
  drop_states(m, out);
  for (std::size_t k = 0; m.h.size() > 1 && k < m.h.size(); ++k) {
    Model c = m;
    erase_at(c.h, k);
    out.push_back(c);
  }
  drop_inputs(m, out);
  drop_params(m, out);
  if (m.has_g) {
    Model c = m;
    c.has_g = c.whole_field = false;
    for (auto& gi : c.g) gi.clear();
    out.push_back(c);
  }
  if (m.whole_field || !m.nominal.empty()) {  // F split back into f and g, no nominal line
    Model c = m;
    c.whole_field = false;
    c.nominal.clear();
    out.push_back(c);
  }
}

void term_candidates(const Model& m, std::vector<Model>& out) {
  std::vector<Terms> Model::*const fields[] = {&Model::f, &Model::g, &Model::h};
  for (auto field : fields) {
    for (std::size_t i = 0; i < (m.*field).size(); ++i) {
      for (std::size_t t = 0; t < (m.*field)[i].size(); ++t) {
        Model c = m;
        auto& comp = (c.*field)[i];
        comp.erase(comp.begin() + static_cast<long>(t));
        out.push_back(c);
      }
    }
  }
}

// The n-th node of f, g, h in preorder (visit_model's order).
Node& nth_node(Model& m, int n) {
  Node* found = nullptr;
  int k = 0;
  visit_model(m, [&](Node& e) {
    if (k++ == n) found = &e;
  });
  return *found;
}

// Every node replaced by each of its children, by 1, 0, the first state, or (a number) 2.
void node_candidates(const Model& m, std::vector<Model>& out) {
  Model probe = m;
  int count = 0;
  visit_model(probe, [&](Node&) { ++count; });
  const std::string first = m.states.empty() ? "1" : m.states[0];
  for (int target = 0; target < count; ++target) {
    const Node node = nth_node(probe, target);
    std::vector<Node> repl = node.kids;
    repl.insert(repl.end(), {num("1"), num("0")});
    if (node.kind == Node::num) repl.push_back(num("2"));
    if (node.kind != Node::sym) repl.push_back(sym(first));
    for (const auto& r : repl) {
      Model c = m;
      nth_node(c, target) = r;
      out.push_back(c);
    }
  }
}

void cosmetic_candidates(const Model& m, std::vector<Model>& out) {
  for (std::size_t k = 0; k < m.domain.size(); ++k) {
    for (const auto& b : {std::pair<double, double>{-1, 1}, {0, 1}, {1, 2}}) {
      Model c = m;
      c.domain[k].lo = b.first;
      c.domain[k].hi = b.second;
      out.push_back(c);
    }
  }
  for (std::size_t i = 0; i < m.states.size(); ++i) {
    const std::string plain = "x" + std::to_string(i + 1);
    bool taken = false;
    for (const auto& s : m.states) taken = taken || s == plain;
    for (const auto& s : m.inputs) taken = taken || s == plain;
    for (const auto& p : m.params) taken = taken || p.name == plain;
    if (taken) continue;
    Model c = m;
    const std::string old = c.states[i];
    c.states[i] = plain;
    for (auto& b : c.domain)
      if (b.name == old) b.name = plain;
    substitute(c, old, sym(plain));
    out.push_back(c);
  }
  if (m.name != "m") {
    Model c = m;
    c.name = "m";
    out.push_back(c);
  }
}

std::vector<Model> candidates(const Model& m) {
  std::vector<Model> out;
  structural_candidates(m, out);
  term_candidates(m, out);
  node_candidates(m, out);
  cosmetic_candidates(m, out);
  const std::size_t size = print_model(m).size();
  out.erase(std::remove_if(out.begin(), out.end(),
                           [&](const Model& c) { return print_model(c).size() >= size; }),
            out.end());
  return out;
}

struct Minimised {
  Model model;
  Finding finding;
  int tests = 0;
};

// Greedy delta debugging on the AST: walk the candidates of the current model; on a success
// take it, recompute its candidates and go on from the same position (the ones before it
// failed already); stop after a pass without success or when the time is up.
Minimised minimise(const Options& o, const Model& m, const Finding& f, const fs::path& dir) {
  // A candidate must reproduce about as fast as the original: one that runs into obsynth's
  // budget is not the same finding, and would make every try cost the whole budget.
  const bool slow = f.kind == "timeout" || f.kind == "compile-timeout";
  const Pipeline pipe(o, slow ? o.budget : std::min(o.budget, std::max(5.0, 4 * f.seconds)));
  Minimised best{m, f, 0};
  const auto t0 = Clock::now();
  std::vector<Model> cands = candidates(m);
  bool progress = false;
  for (std::size_t k = 0; seconds_since(t0) < o.minimise_seconds;) {
    if (k >= cands.size()) {
      if (!progress) break;
      progress = false;
      k = 0;
      continue;
    }
    const fs::path d = dir / ("try" + std::to_string(best.tests++));
    const UnitResult r = pipe.run_unit(f.unit, cands[k], d);
    std::error_code ec;
    fs::remove_all(d, ec);
    if (!r.finding || r.finding->kind != f.kind || r.finding->key != f.key) {
      ++k;
      continue;
    }
    best.model = cands[k];
    best.finding = *r.finding;
    cands = candidates(best.model);
    progress = true;
  }
  return best;
}

// ---- driver -----------------------------------------------------------------------------
struct Stats {
  std::mutex mu;
  std::map<std::string, std::map<std::string, int>> codes;  // step -> exit code -> runs
  std::map<std::string, double> seconds;
  std::map<std::string, int> findings;  // kind -> count
  std::set<std::string> classes;        // unit|kind|key already minimised
  long models = 0;
  bool stop = false;
};

std::string finding_header(const Options& o, std::uint64_t index, const Finding& f,
                           const std::string& what) {
  std::string s = "# pipeline_fuzz finding (" + what + "): " + f.kind +
                  (f.key.empty() ? "" : " (" + f.key + ")") + " in '" + f.unit + "'\n";
  s += "# seed " + std::to_string(o.seed) + ", model " + std::to_string(index) +
       ": pipeline_fuzz --seed " + std::to_string(o.seed) + " --first-index " +
       std::to_string(index) + " --models 1" + (o.quick ? " --quick" : "") + "\n";
  s += "# command: " + f.command + "\n";
  std::istringstream ev(head_lines(f.evidence, 12));
  std::string line;
  while (std::getline(ev, line)) s += "#   " + line.substr(0, 200) + "\n";
  return s;
}

class Driver {
 public:
  explicit Driver(const Options& o) : o_(o), pipe_(o, o.budget) {}
  int run();

 private:
  const Options& o_;
  Pipeline pipe_;
  Stats stats_;
  std::atomic<std::uint64_t> next_{0};
  std::mutex print_mu_;
  Clock::time_point t0_ = Clock::now();

  void worker();
  void one_model(std::uint64_t index);
  void record(const std::string& unit, const UnitResult& r);
  void report_finding(std::uint64_t index, const Model& m, const Finding& f, const fs::path& dir);
  void report_duplicate(std::uint64_t index, const Model& m, const Finding& f);
  bool more(std::uint64_t k);
  void summary();
};

bool Driver::more(std::uint64_t k) {
  {
    std::lock_guard<std::mutex> lock(stats_.mu);
    if (stats_.stop) return false;
  }
  if (o_.models >= 0 && k >= static_cast<std::uint64_t>(o_.models)) return false;
  if (o_.seconds > 0 && seconds_since(t0_) >= o_.seconds) return false;
  return o_.models >= 0 || o_.seconds > 0 || k < 20;
}

void Driver::worker() {
  for (std::uint64_t k = next_++; more(k); k = next_++) one_model(o_.first_index + k);
}

void Driver::record(const std::string& unit, const UnitResult& r) {
  std::lock_guard<std::mutex> lock(stats_.mu);
  for (const auto& s : r.steps) {
    const std::string name = s.label.empty() ? unit : unit + " cc";
    ++stats_.codes[name][code_text(s.run)];
    stats_.seconds[name] += s.run.seconds;
  }
}

void Driver::one_model(std::uint64_t index) {
  const Model m = Generator(o_.seed, index).generate();
  const fs::path dir =
      fs::path(o_.work) / ("s" + std::to_string(o_.seed) + "-" + std::to_string(index));
  std::string line = "seed " + std::to_string(o_.seed) + " #" + std::to_string(index) +
                     " n=" + std::to_string(m.states.size()) +
                     " m=" + std::to_string(m.inputs.size()) + " p=" + std::to_string(m.h.size()) +
                     " |";
  std::vector<Finding> found;
  std::string notes;
  for (const auto& unit : kUnits) {
    if (!runs_unit(o_, unit)) continue;
    const UnitResult r = pipe_.run_unit(unit, m, dir / unit);
    record(unit, r);
    for (const auto& s : r.steps) {
      line += " " + (s.label.empty() ? unit : s.label) + " " + code_text(s.run) + " " +
              fixed(s.run.seconds, 1) + "s";
      if (o_.verbose && s.run.exit_code == 1)
        notes += "    " + unit + ": " + first_error(s.run.err);
    }
    if (r.finding) {
      line += " [FINDING " + r.finding->kind + "]";
      found.push_back(*r.finding);
    }
  }
  {
    std::lock_guard<std::mutex> lock(print_mu_);
    std::printf("%s\n%s", line.c_str(), notes.c_str());
    std::fflush(stdout);
  }
  for (const auto& f : found) report_finding(index, m, f, dir);
  std::error_code ec;
  if (!o_.keep_work) fs::remove_all(dir, ec);
  std::lock_guard<std::mutex> lock(stats_.mu);
  ++stats_.models;
}

void Driver::report_finding(std::uint64_t index, const Model& m, const Finding& f,
                            const fs::path& dir) {
  bool seen = false;
  {
    std::lock_guard<std::mutex> lock(stats_.mu);
    ++stats_.findings[f.kind];
    if (!o_.keep_going) stats_.stop = true;
    seen = !stats_.classes.insert(f.unit + "|" + f.kind + "|" + f.key).second;
  }
  if (seen) return report_duplicate(index, m, f);
  Minimised mini{m, f, 0};
  if (o_.minimise) mini = minimise(o_, m, f, dir / ("min-" + f.unit));
  const std::string min_text = print_model(mini.model);
  const std::string stem = f.kind + "-" + hex8(fnv1a(f.unit + min_text));
  const fs::path out = o_.findings;
  fs::create_directories(out);
  write_file(out / (stem + ".orig.sym"), finding_header(o_, index, f, "original") + print_model(m));
  write_file(out / (stem + ".min.sym"),
             finding_header(o_, index, mini.finding, "minimised") + min_text);
  write_file(out / (stem + ".log"),
             "command: " + mini.finding.command + "\n\n" + mini.finding.evidence);
  std::lock_guard<std::mutex> lock(print_mu_);
  std::printf(
      "FINDING %s in '%s' (seed %llu, model %llu%s): %s.min.sym (%d minimisation runs)\n%s\n",
      f.kind.c_str(), f.unit.c_str(), static_cast<unsigned long long>(o_.seed),
      static_cast<unsigned long long>(index), f.key.empty() ? "" : (", " + f.key).c_str(),
      (out / stem).c_str(), mini.tests, min_text.c_str());
  std::fflush(stdout);
}

// A finding of a class already minimised in this run: its model is kept, not minimised again.
void Driver::report_duplicate(std::uint64_t index, const Model& m, const Finding& f) {
  const std::string text = print_model(m);
  const fs::path stem = fs::path(o_.findings) / (f.kind + "-" + hex8(fnv1a(f.unit + text)));
  fs::create_directories(o_.findings);
  write_file(stem.string() + ".orig.sym", finding_header(o_, index, f,
                                                         "same class as an earlier "
                                                         "finding, not minimised") +
                                              text);
  std::lock_guard<std::mutex> lock(print_mu_);
  std::printf(
      "FINDING %s in '%s' (seed %llu, model %llu): same class as an earlier one, %s.orig.sym\n",
      f.kind.c_str(), f.unit.c_str(), static_cast<unsigned long long>(o_.seed),
      static_cast<unsigned long long>(index), stem.c_str());
  std::fflush(stdout);
}

void Driver::summary() {
  std::printf("\npipeline_fuzz: %ld models (seed %llu from index %llu) in %.1f s\n", stats_.models,
              static_cast<unsigned long long>(o_.seed),
              static_cast<unsigned long long>(o_.first_index), seconds_since(t0_));
  for (const auto& [step, codes] : stats_.codes) {
    int runs = 0;
    std::string detail;
    for (const auto& [code, count] : codes) {
      runs += count;
      detail += " " + code + ":" + std::to_string(count);
    }
    std::printf("  %-18s %4d runs %8.1f s  exit%s\n", step.c_str(), runs, stats_.seconds[step],
                detail.c_str());
  }
  int total = 0;
  std::string kinds;
  for (const auto& [kind, count] : stats_.findings) {
    total += count;
    kinds += " " + kind + ":" + std::to_string(count);
  }
  std::printf("findings: %d (%zu classes)%s%s\n", total, stats_.classes.size(), kinds.c_str(),
              total ? (" (in " + o_.findings + ")").c_str() : "");
}

int Driver::run() {
  std::vector<std::thread> threads;
  for (int k = 0; k < o_.jobs; ++k) threads.emplace_back([this] { worker(); });
  for (auto& t : threads) t.join();
  summary();
  return stats_.findings.empty() ? 0 : 1;
}

// ---- command line -----------------------------------------------------------------------
const char* const kUsage =
    "usage: pipeline_fuzz [--seed S] [--models N | --seconds T] [--obsynth PATH] [--jobs J]\n"
    "                     [--findings DIR] [--keep-going] [--quick] [options]\n"
    "  --seed S             models come from (S, index): same seed, same models (default 1)\n"
    "  --models N           number of models (default 20, unlimited with --seconds)\n"
    "  --seconds T          start no new model after T seconds\n"
    "  --first-index K      first model index (reproduce model K of a seed: --models 1)\n"
    "  --obsynth PATH       obsynth binary (default build/synth/obsynth)\n"
    "  --source-dir DIR     obsynth source tree: runtime/ and tests/lsan.supp (default .)\n"
    "  --eigen-include DIR  Eigen's include directory (default /usr/include/eigen3; ';' lists)\n"
    "  --cxx CXX, --cc CC   compilers of the generated code (default g++, gcc)\n"
    "  --jobs J             models run in parallel (default 1)\n"
    "  --findings DIR       where findings go (default fuzz/pipeline-findings)\n"
    "  --keep-going         go on after a finding (default: stop starting new models)\n"
    "  --quick              skip --method all and --certify, shorter simulate (CI run)\n"
    "  --budget SECONDS     obsynth's --total-seconds per command (default 60); killed at\n"
    "                       1.5 x budget + 5 s\n"
    "  --max-memory SIZE    obsynth's --max-memory (default 4G)\n"
    "  --no-minimise        write findings as found\n"
    "  --minimise-seconds T time spent minimising one finding (default 600)\n"
    "  --flag-inf           also count 'inf' printed in a text report as a finding\n"
    "  --work DIR           scratch directory (default $TMPDIR/pipeline-fuzz-<pid>)\n"
    "  --keep-work          keep the scratch directory\n"
    "  --verbose            print each exit-1 diagnostic (first error line)\n"
    "  --units LIST         run only these units (comma-separated): check, check-json,\n"
    "                       check-certify, main-auto, main-auto-c, main-all, main-all-c, simulate\n"
    "  --dump DIR           only write the models (DIR/<seed>-<index>.sym), run nothing\n"
    "Exit status: 0 no finding, 1 findings, 2 usage or harness error.\n";

[[noreturn]] void usage_error(const std::string& msg) {
  std::fprintf(stderr, "pipeline_fuzz: %s\n%s", msg.c_str(), kUsage);
  std::exit(2);
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(s);
  while (std::getline(in, item, sep))
    if (!item.empty()) out.push_back(item);
  return out;
}

bool parse_flag(Options& o, const std::string& a) {
  if (a == "--keep-going") return o.keep_going = true;
  if (a == "--quick") return o.quick = true;
  if (a == "--no-minimise") return !(o.minimise = false);
  if (a == "--flag-inf") return o.flag_inf = true;
  if (a == "--keep-work") return o.keep_work = true;
  if (a == "--verbose") return o.verbose = true;
  return false;
}

using Setter = std::function<void(Options&, const std::string&)>;

const std::map<std::string, Setter>& setters() {
  static const std::map<std::string, Setter> table = {
      {"--seed", [](Options& o, const std::string& v) { o.seed = std::stoull(v); }},
      {"--first-index", [](Options& o, const std::string& v) { o.first_index = std::stoull(v); }},
      {"--models", [](Options& o, const std::string& v) { o.models = std::stol(v); }},
      {"--seconds", [](Options& o, const std::string& v) { o.seconds = std::stod(v); }},
      {"--obsynth", [](Options& o, const std::string& v) { o.obsynth = v; }},
      {"--source-dir", [](Options& o, const std::string& v) { o.source_dir = v; }},
      {"--eigen-include",
       [](Options& o, const std::string& v) { o.eigen_include = split(v, ';'); }},
      {"--cxx", [](Options& o, const std::string& v) { o.cxx = v; }},
      {"--cc", [](Options& o, const std::string& v) { o.cc = v; }},
      {"--jobs", [](Options& o, const std::string& v) { o.jobs = std::max(1, std::stoi(v)); }},
      {"--findings", [](Options& o, const std::string& v) { o.findings = v; }},
      {"--budget", [](Options& o, const std::string& v) { o.budget = std::stod(v); }},
      {"--max-memory", [](Options& o, const std::string& v) { o.max_memory = v; }},
      {"--minimise-seconds",
       [](Options& o, const std::string& v) { o.minimise_seconds = std::stod(v); }},
      {"--work", [](Options& o, const std::string& v) { o.work = v; }},
      {"--dump", [](Options& o, const std::string& v) { o.dump = v; }},
      {"--units", [](Options& o, const std::string& v) { o.units = split(v, ','); }}};
  return table;
}

void parse_value(Options& o, const std::string& a, const std::string& v) {
  const auto it = setters().find(a);
  if (it == setters().end()) usage_error("unknown option " + a);
  try {
    it->second(o, v);
  } catch (const std::logic_error&) {
    usage_error("bad value '" + v + "' for " + a);
  }
}

Options parse_options(int argc, char** argv) {
  Options o;
  for (int k = 1; k < argc; ++k) {
    const std::string a = argv[k];
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    }
    if (parse_flag(o, a)) continue;
    if (k + 1 >= argc) usage_error("missing value after " + a);
    parse_value(o, a, argv[++k]);
  }
  return o;
}

// Absolute paths (the commands run from scratch directories), sanitizer defaults, scratch dir.
void prepare(Options& o) {
  std::error_code ec;
  const fs::path bin = fs::absolute(o.obsynth, ec);
  if (!fs::exists(bin)) usage_error("no obsynth binary at " + o.obsynth);
  o.obsynth = bin.string();
  o.source_dir = fs::absolute(o.source_dir).lexically_normal().string();
  if (!fs::exists(fs::path(o.source_dir) / "runtime" / "obsynth"))
    usage_error("no runtime/obsynth under --source-dir " + o.source_dir);
  for (const auto& u : o.units)
    if (std::find(kUnits.begin(), kUnits.end(), u) == kUnits.end()) usage_error("no unit " + u);
  const char* tmp = std::getenv("TMPDIR");
  if (o.work.empty())
    o.work =
        (fs::path(tmp ? tmp : "/tmp") / ("pipeline-fuzz-" + std::to_string(getpid()))).string();
  o.work = fs::absolute(o.work).string();
  fs::create_directories(o.work);
  const std::string supp = (fs::path(o.source_dir) / "tests" / "lsan.supp").string();
  setenv("ASAN_OPTIONS", "detect_leaks=1:abort_on_error=1", 0);
  setenv("LSAN_OPTIONS", ("suppressions=" + supp + ":print_suppressions=0").c_str(), 0);
  setenv("UBSAN_OPTIONS", "print_stacktrace=1:halt_on_error=1", 0);
  rlimit core{0, 0};  // no core files from crashing runs
  setrlimit(RLIMIT_CORE, &core);
}

int dump_models(const Options& o) {
  fs::create_directories(o.dump);
  const long count = o.models >= 0 ? o.models : 20;
  for (long k = 0; k < count; ++k) {
    const std::uint64_t index = o.first_index + static_cast<std::uint64_t>(k);
    const Model m = Generator(o.seed, index).generate();
    write_file(fs::path(o.dump) / (std::to_string(o.seed) + "-" + std::to_string(index) + ".sym"),
               print_model(m));
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o = parse_options(argc, argv);
  if (!o.dump.empty()) return dump_models(o);
  prepare(o);
  const int rc = Driver(o).run();
  std::error_code ec;
  if (!o.keep_work) fs::remove_all(o.work, ec);
  return rc;
}
