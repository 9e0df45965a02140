// Expression DAG for code generation: GiNaC expressions are converted, unexpanded, into
// hash-consed nodes, so that common subexpressions across all outputs of a function become
// one node (design.md §5: emit from the unexpanded DAG with CSE). Operands of sums and
// products are ordered by a structural hash computed from content only, so emission order
// (and hence the generated text) does not depend on GiNaC's run-dependent term order.
#pragma once

#include <ginac/ginac.h>

#include <cstdint>
#include <deque>
#include <map>
#include <string>
#include <unordered_map>
#include <vector>

namespace obsynth {

enum class NodeOp {
  constant,  // value (rational or floating)
  variable,  // name
  add,       // args
  mul,       // args
  div,       // args[0] / args[1]
  neg,       // -args[0]
  pow_int,   // args[0]^exponent, exponent >= 2
  sqrt,      // sqrt(args[0])
  pow_real,  // args[0]^value (non-integer rational exponent other than 1/2)
  call,      // name(args[0]): sin cos tan exp log tanh atan atanh
};

struct Node {
  NodeOp op;
  std::vector<int> args;
  GiNaC::numeric value;  // constant value, or exponent for pow_real
  long exponent = 0;     // pow_int
  std::string name;      // variable or function name
  std::uint64_t hash = 0;
};

class Dag {
 public:
  // Adds an expression; returns its node id. Equal subexpressions share ids.
  int add(const GiNaC::ex& e);
  // A local definition: from now on the symbol stands for the node of `value` (added first).
  // Elimination sequences are bound step by step this way instead of being substituted into
  // each other with GiNaC, whose evaluation pulls contents out of powers of sums (factors
  // 2^(2^k) along nested squares, which overflow in floating point).
  int let(const GiNaC::symbol& s, const GiNaC::ex& value);
  int constant(const GiNaC::numeric& v);
  int variable(const std::string& name);

  const Node& node(int id) const { return nodes_[static_cast<std::size_t>(id)]; }
  std::size_t size() const { return nodes_.size(); }

 private:
  int intern(Node n);
  int convert(const GiNaC::ex& e);
  int convert_owned(const GiNaC::ex& e);
  int make(NodeOp op, std::vector<int> args, bool commutative);
  bool is_negative(int id) const;  // a negation or a negative constant
  int negate(int a);
  int sum(const std::vector<int>& terms);
  int factor(const GiNaC::ex& f, bool& negated);

  std::vector<Node> nodes_;
  std::map<std::string, int> index_;  // structural key -> id
  std::unordered_map<const GiNaC::basic*, int> memo_;
  std::map<std::string, int> bound_;  // let-bound symbol names
  std::deque<GiNaC::ex> keep_alive_;  // memo_ keys must outlive the map
};

// Double-precision evaluation of a set of expressions through their DAG: the same
// operations, in the same order, as the emitted C++ (used by `obsynth simulate` and tests).
class NumericFunction {
 public:
  NumericFunction() = default;
  // inputs: variable names in the order of the argument vector.
  NumericFunction(const std::vector<GiNaC::ex>& outputs, const std::vector<std::string>& inputs);
  // With local definitions (symbol, value), bound in order before the outputs (Dag::let).
  NumericFunction(const std::vector<std::pair<GiNaC::symbol, GiNaC::ex>>& lets,
                  const std::vector<GiNaC::ex>& outputs, const std::vector<std::string>& inputs);
  std::vector<double> operator()(const std::vector<double>& in) const;
  std::size_t outputs() const { return out_ids_.size(); }

 private:
  Dag dag_;
  std::vector<int> out_ids_;
  std::vector<int> order_;          // needed nodes, children first
  std::vector<int> input_of_node_;  // node id -> argument index (variables)
  mutable std::vector<double> values_;
};

}  // namespace obsynth
