// Models built by construction for property tests: a canonical form z' = A z + l(u, y),
// y = z_n, pulled back through a known triangular diffeomorphism T, so that T, l and T^-1
// are known independently of the pipeline.
#pragma once

#include <ginac/ginac.h>

#include <functional>
#include <string>
#include <vector>

#include "front/model.hpp"

namespace obsynth::testing {

// polynomial / transcendental: T from the lists below, l with polynomial or exp/sin/atan terms
// (used for the analysis tests). stable / stable_newton: l(u, y) = -a y + bounded terms with
// s^n + a_n s^(n-1) + ... Hurwitz, so trajectories stay bounded (closed-loop tests);
// stable_newton adds x_n^3/3 to the row of x_n, so T^-1 has no closed form (runtime Newton).
enum class Flavor { polynomial, transcendental, stable, stable_newton };

struct Constructed {
  Model model;
  ExVec T;          // the diffeomorphism used, T(0) = 0
  ExVec T_inverse;  // in z1..zn (symbols named z1..zn)
  ExVec l;          // in u and y (symbols named u, y)
  std::vector<GiNaC::symbol> z;
  GiNaC::symbol y;
};

// T_n = x1, T_{n-k} = x_{k+1} + psi_k(x_1..x_k), psi_k from a fixed list (polynomial,
// or exp/sin/atan); f = (dT/dx)^-1 (A T + l(0, x1)), g = (dT/dx)^-1 (l(u, x1) - l(0, x1)).
// extra_g (in z coordinates, may use u) is added to the input part to break C3 on purpose.
// A perturbation in z coordinates: component vector given the symbols z1..zn and u.
using Perturbation =
    std::function<ExVec(const std::vector<GiNaC::symbol>& z, const GiNaC::symbol& u)>;

Constructed linearizable_chain(std::size_t n, Flavor flavor, const Perturbation& extra_f_z = {},
                               const Perturbation& extra_g_z = {});

// Families whose T and l exercise one kind of closed-form antiderivative each (n >= 2):
// T_{n-k} = s_k(x1) x_{k+1} + psi_k(x_1..x_k), T_n = x1, l_1 with the input term u (1 + y^2).
//  tanh_friction: psi with x_k tanh(x1), l with tanh(2y), tanh(y), y tanh(y);
//  exp_cancel:    s_k = exp(x1) or exp(2 x1) (f carries exp(-x1), exp(-2 x1), so Lie
//                 derivatives multiply exp(a) by exp(-a)), l with exp(-y), exp(2y);
//  poly_exp:      psi with x1^2 exp(x1) x_k, l with y^2 exp(y), y exp(y), y exp(-y);
//  poly_sin:      psi with x1 sin(x1) x_k, l with y sin(y), y^2 cos(y), exp(2y) cos(y);
//  atan:          psi with atan(x_k) and x_k atan(x1), l with y atan(y), atan(y), y^2/(1+y^2).
enum class Family { tanh_friction, exp_cancel, poly_exp, poly_sin, atan };
const char* family_name(Family f);
Constructed linearizable_family(std::size_t n, Family family);

// The model as .sym text (parseable by obsynth's front end).
std::string to_sym(const Model& m);

// Solve (dT/dx) v = w for the triangular Jacobian of the chain above.
ExVec pull_back(const ExVec& T, const std::vector<GiNaC::symbol>& x, const ExVec& w);

}  // namespace obsynth::testing
