# Three modes with Duffing terms, pairwise dispersive coupling, and one three-mode cubic term.
#
#   U = sum_i beta_i/4 q_i^4 + sum_{i<j} g_ij/2 q_i^2 q_j^2 + mu/2 q1^2 q2 q3
#
# The mu term couples resonantly when 2 f1 = f2 + f3 (degenerate four-wave mixing: two quanta
# of mode 1 convert into one of mode 2 and one of mode 3). The modes below satisfy it:
# 2 x 1.0 MHz = 0.8 MHz + 1.2 MHz.

mode q1 at 1.0 MHz, Q = 2e4          # Q1 known from a ring-down, fixed
mode q2 at 0.8 MHz
mode q3 at 1.2 MHz

for i in 1..3: param beta[i]
for i<j in 1..3: param g[i,j]
param mu

for i in 1..3: potential: beta[i]/4 * q[i]^4
for i<j in 1..3: potential: g[i,j]/2 * q[i]^2 * q[j]^2
potential: mu/2 * q1^2*q2*q3
