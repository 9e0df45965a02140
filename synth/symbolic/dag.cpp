#include "symbolic/dag.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "foundation/diagnostics.hpp"

namespace obsynth {

using GiNaC::ex;
using GiNaC::is_a;
using GiNaC::numeric;

namespace {

std::uint64_t mix(std::uint64_t h, std::uint64_t v) {
  h ^= v + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
  h *= 0xff51afd7ed558ccdULL;
  return h ^ (h >> 33);
}

std::uint64_t hash_string(const std::string& s) {
  std::uint64_t h = 1469598103934665603ULL;  // FNV-1a
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ULL;
  return h;
}

std::string numeric_text(const numeric& v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

}  // namespace

int Dag::intern(Node n) {
  std::string key = fmt::format(
      "{}|{}|{}|{}|", static_cast<int>(n.op), n.name, n.exponent,
      n.op == NodeOp::constant || n.op == NodeOp::pow_real ? numeric_text(n.value) : "");
  for (int a : n.args) key += std::to_string(a) + ",";
  auto it = index_.find(key);
  if (it != index_.end()) return it->second;
  std::uint64_t h = mix(static_cast<std::uint64_t>(n.op) + 1, hash_string(n.name));
  h = mix(h, static_cast<std::uint64_t>(n.exponent));
  if (n.op == NodeOp::constant || n.op == NodeOp::pow_real)
    h = mix(h, hash_string(numeric_text(n.value)));
  for (int a : n.args) h = mix(h, nodes_[static_cast<std::size_t>(a)].hash);
  n.hash = h;
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back(std::move(n));
  index_.emplace(std::move(key), id);
  return id;
}

int Dag::constant(const numeric& v) {
  Node n;
  n.op = NodeOp::constant;
  n.value = v;
  return intern(std::move(n));
}

int Dag::variable(const std::string& name) {
  Node n;
  n.op = NodeOp::variable;
  n.name = name;
  return intern(std::move(n));
}

int Dag::make(NodeOp op, std::vector<int> args, bool commutative) {
  if (commutative) {
    // Content order: by structural hash (ties impossible in practice; id as last resort
    // only matters for identical nodes, which are the same id anyway).
    std::sort(args.begin(), args.end(), [&](int a, int b) {
      const auto ha = nodes_[static_cast<std::size_t>(a)].hash,
                 hb = nodes_[static_cast<std::size_t>(b)].hash;
      return ha != hb ? ha < hb : a < b;
    });
  }
  Node n;
  n.op = op;
  n.args = std::move(args);
  return intern(std::move(n));
}

int Dag::negate(int a) {
  const Node& n = nodes_[static_cast<std::size_t>(a)];
  if (n.op == NodeOp::neg) return n.args[0];
  if (n.op == NodeOp::constant) return constant(-n.value);
  return make(NodeOp::neg, {a}, false);
}

// GiNaC gives a sum either sign from run to run (normal() returns (u - a)/J or -(a - u)/J, and
// products distribute their coefficient differently), so of S and -S the DAG keeps the sum
// with fewer negative terms, ties broken by the smaller content hash, and a negation node
// takes the difference: the DAG, and the emitted text, do not depend on GiNaC's choice.
bool Dag::is_negative(int id) const {
  const Node& n = nodes_[static_cast<std::size_t>(id)];
  return n.op == NodeOp::neg || (n.op == NodeOp::constant && n.value.is_negative());
}

int Dag::sum(const std::vector<int>& terms) {
  const auto negative = static_cast<std::size_t>(
      std::count_if(terms.begin(), terms.end(), [&](int t) { return is_negative(t); }));
  const int plus = make(NodeOp::add, terms, true);
  if (2 * negative < terms.size()) return plus;
  std::vector<int> flipped;
  for (int t : terms) flipped.push_back(negate(t));
  const int minus = make(NodeOp::add, flipped, true);
  bool flip = 2 * negative > terms.size();
  if (!flip) {  // a tie: prefer the sum printed with a leading plus (a - b, not -(-a + b))
    const bool plus_leads = !is_negative(nodes_[static_cast<std::size_t>(plus)].args[0]),
               minus_leads = !is_negative(nodes_[static_cast<std::size_t>(minus)].args[0]);
    flip = plus_leads != minus_leads ? minus_leads
                                     : nodes_[static_cast<std::size_t>(minus)].hash <
                                           nodes_[static_cast<std::size_t>(plus)].hash;
  }
  return flip ? make(NodeOp::neg, {minus}, false) : plus;
}

// A factor of a product without its sign (the product's coefficient absorbs it).
int Dag::factor(const ex& f, bool& negated) {
  const int id = convert(f);
  const Node& n = nodes_[static_cast<std::size_t>(id)];
  negated = n.op == NodeOp::neg;
  return negated ? n.args[0] : id;
}

int Dag::add(const ex& e) {
  keep_alive_.push_back(e);
  return convert(e);
}

int Dag::let(const GiNaC::symbol& s, const ex& value) {
  const int id = add(value);
  bound_[s.get_name()] = id;
  return id;
}

// Temporaries must stay alive: the memo is keyed by node address.
int Dag::convert_owned(const ex& e) {
  keep_alive_.push_back(e);
  return convert(keep_alive_.back());
}

int Dag::convert(const ex& e) {
  auto m = memo_.find(&GiNaC::ex_to<GiNaC::basic>(e));
  if (m != memo_.end()) return m->second;
  int id = -1;
  if (is_a<numeric>(e)) {
    id = constant(GiNaC::ex_to<numeric>(e));
  } else if (is_a<GiNaC::symbol>(e)) {
    const std::string& name = GiNaC::ex_to<GiNaC::symbol>(e).get_name();
    const auto bound = bound_.find(name);
    id = bound != bound_.end() ? bound->second : variable(name);
  } else if (is_a<GiNaC::add>(e)) {
    std::vector<int> args;
    for (std::size_t i = 0; i < e.nops(); ++i) args.push_back(convert(e.op(i)));
    id = sum(args);
  } else if (is_a<GiNaC::mul>(e)) {
    std::vector<int> num, den;
    numeric coeff = 1;
    for (std::size_t i = 0; i < e.nops(); ++i) {
      const ex f = e.op(i);
      bool negated = false;
      if (is_a<numeric>(f)) {
        coeff *= GiNaC::ex_to<numeric>(f);
      } else if (is_a<GiNaC::power>(f) && is_a<numeric>(f.op(1)) &&
                 GiNaC::ex_to<numeric>(f.op(1)).is_negative()) {
        const ex positive = GiNaC::pow(f.op(0), -f.op(1));
        keep_alive_.push_back(positive);
        den.push_back(factor(keep_alive_.back(), negated));
      } else {
        num.push_back(factor(f, negated));
      }
      if (negated) coeff = -coeff;
    }
    // One rational literal per product (a multiplication, cheaper than a division).
    const bool negate = coeff.is_negative();
    const numeric a = GiNaC::abs(coeff);
    if (a != 1) num.push_back(constant(a));
    int top = num.empty() ? constant(1) : (num.size() == 1 ? num[0] : make(NodeOp::mul, num, true));
    if (!den.empty()) {
      const int bottom = den.size() == 1 ? den[0] : make(NodeOp::mul, den, true);
      top = make(NodeOp::div, {top, bottom}, false);
    }
    id = negate ? make(NodeOp::neg, {top}, false) : top;
  } else if (is_a<GiNaC::power>(e)) {
    const ex b = e.op(0), x = e.op(1);
    OBSYNTH_ASSERT(is_a<numeric>(x), "symbolic exponents are rejected by the parser");
    const numeric q = GiNaC::ex_to<numeric>(x);
    if (q.is_negative()) {
      keep_alive_.push_back(GiNaC::pow(b, -q));
      bool negated = false;
      id = make(NodeOp::div, {constant(1), factor(keep_alive_.back(), negated)}, false);
      if (negated) id = make(NodeOp::neg, {id}, false);
    } else if (q.is_integer()) {
      bool negated = false;  // (-b)^k = (-1)^k b^k
      const long k = q.to_long();
      Node n;
      n.op = NodeOp::pow_int;
      n.args = {factor(b, negated)};
      n.exponent = k;
      id = intern(std::move(n));
      if (negated && k % 2 == 1) id = make(NodeOp::neg, {id}, false);
    } else if (q == numeric(1, 2)) {
      id = make(NodeOp::sqrt, {convert(b)}, false);
    } else if (q.denom() == 2) {
      // b^(k/2) = b^((k-1)/2) * sqrt(b)
      id = make(NodeOp::mul,
                {convert_owned(GiNaC::pow(b, (q - numeric(1, 2)))),
                 make(NodeOp::sqrt, {convert(b)}, false)},
                true);
    } else {
      Node n;
      n.op = NodeOp::pow_real;
      n.args = {convert(b)};
      n.value = q;
      id = intern(std::move(n));
    }
  } else if (is_a<GiNaC::function>(e)) {
    OBSYNTH_ASSERT(e.nops() == 1, "only unary functions are supported");
    Node n;
    n.op = NodeOp::call;
    n.name = GiNaC::ex_to<GiNaC::function>(e).get_name();
    n.args = {convert(e.op(0))};
    id = intern(std::move(n));
  } else if (is_a<GiNaC::constant>(e)) {
    id = constant(GiNaC::ex_to<numeric>(GiNaC::evalf(e)));
  } else {
    OBSYNTH_ASSERT(false, "unsupported expression in code generation");
  }
  // GiNaC builds operands of sums and products on the fly (op(i) of an add or mul is a new
  // object), so the memo keeps every key alive: a freed address must never be looked up.
  keep_alive_.push_back(e);
  memo_.emplace(&GiNaC::ex_to<GiNaC::basic>(keep_alive_.back()), id);
  return id;
}

NumericFunction::NumericFunction(const std::vector<ex>& outputs,
                                 const std::vector<std::string>& inputs)
    : NumericFunction({}, outputs, inputs) {}

NumericFunction::NumericFunction(const std::vector<std::pair<GiNaC::symbol, ex>>& lets,
                                 const std::vector<ex>& outputs,
                                 const std::vector<std::string>& inputs) {
  for (const auto& [s, value] : lets) dag_.let(s, value);
  for (const auto& e : outputs) out_ids_.push_back(dag_.add(e));
  std::vector<bool> needed(dag_.size(), false);
  std::vector<int> stack(out_ids_.begin(), out_ids_.end());
  while (!stack.empty()) {
    const int id = stack.back();
    stack.pop_back();
    if (needed[static_cast<std::size_t>(id)]) continue;
    needed[static_cast<std::size_t>(id)] = true;
    for (int a : dag_.node(id).args) stack.push_back(a);
  }
  input_of_node_.assign(dag_.size(), -1);
  for (std::size_t id = 0; id < dag_.size(); ++id) {
    if (!needed[id]) continue;
    order_.push_back(static_cast<int>(id));  // ids are created children first
    const Node& n = dag_.node(static_cast<int>(id));
    if (n.op == NodeOp::variable) {
      auto it = std::find(inputs.begin(), inputs.end(), n.name);
      OBSYNTH_ASSERT(it != inputs.end(), "numeric function: unbound variable " + n.name);
      input_of_node_[id] = static_cast<int>(it - inputs.begin());
    }
  }
  values_.assign(dag_.size(), 0.0);
}

std::vector<double> NumericFunction::operator()(const std::vector<double>& in) const {
  for (int id : order_) {
    const Node& n = dag_.node(id);
    auto arg = [&](std::size_t i) { return values_[static_cast<std::size_t>(n.args[i])]; };
    double v = 0;
    switch (n.op) {
      case NodeOp::constant:
        v = n.value.to_double();
        break;
      case NodeOp::variable:
        v = in[static_cast<std::size_t>(input_of_node_[static_cast<std::size_t>(id)])];
        break;
      case NodeOp::add:
        v = arg(0);
        for (std::size_t i = 1; i < n.args.size(); ++i) v += arg(i);
        break;
      case NodeOp::mul:
        v = arg(0);
        for (std::size_t i = 1; i < n.args.size(); ++i) v *= arg(i);
        break;
      case NodeOp::div:
        v = arg(0) / arg(1);
        break;
      case NodeOp::neg:
        v = -arg(0);
        break;
      case NodeOp::pow_int: {
        const double b = arg(0);
        v = b;
        for (long k = 1; k < n.exponent; ++k) v *= b;
        break;
      }
      case NodeOp::sqrt:
        v = std::sqrt(arg(0));
        break;
      case NodeOp::pow_real:
        v = std::pow(arg(0), n.value.to_double());
        break;
      case NodeOp::call: {
        const double a = arg(0);
        if (n.name == "sin")
          v = std::sin(a);
        else if (n.name == "cos")
          v = std::cos(a);
        else if (n.name == "tan")
          v = std::tan(a);
        else if (n.name == "exp")
          v = std::exp(a);
        else if (n.name == "log")
          v = std::log(a);
        else if (n.name == "tanh")
          v = std::tanh(a);
        else if (n.name == "atan")
          v = std::atan(a);
        else if (n.name == "atanh")
          v = std::atanh(a);
        else
          OBSYNTH_ASSERT(false, "unsupported function " + n.name);
        break;
      }
    }
    values_[static_cast<std::size_t>(id)] = v;
  }
  std::vector<double> out;
  out.reserve(out_ids_.size());
  for (int id : out_ids_) out.push_back(values_[static_cast<std::size_t>(id)]);
  return out;
}

}  // namespace obsynth
