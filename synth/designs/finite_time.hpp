// Finite-time epsilon-T observer (seed 004, Garcia & Hernandez, after Kreisselmeier & Engel):
// a bank of stable first-order filters z' = A z + b y (A diagonal, prescribed eigenvalues), the
// delay line eta = z(t) - e^{AT} z(t - T) (= q(x(t)) once T has passed, eq. 8), and an
// approximate inverse of the observation map q, tabulated per input level (eq. 12-13, 15):
//   q_k(xi) = int_0^T e^{A s} b h(x(-s; xi, u_k)) ds  (backward simulation, u frozen at u_k),
//   Q_k(eta) = sum_i x_i w_i / sum_i w_i,  w_i = (eps + |q_k(x_i) - eta|)^-power,
// over a regular grid x_i of the model's domain box. Between input levels the default rule
// interpolates q linearly in the input's window mean (finite_time.cpp, choose_kernel).
// Needs no derivative of f or h: it accepts non-smooth outputs such as the half-wave rectifier
// of seed 004's example (14).
#pragma once

#include "designs/registry.hpp"

namespace obsynth {

Design finite_time_design();

}  // namespace obsynth
