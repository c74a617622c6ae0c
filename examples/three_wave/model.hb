# Three-wave mixing between three modes whose frequencies satisfy f3 = f1 + f2, so the quadratic
# coupling kappa q1 q2 q3 is resonant: driving q1 and q2 pumps q3 at their sum frequency (and q3
# with q1 pumps q2 at the difference f3 - f1).
#
#   U = kappa q1 q2 q3 + sum_i beta_i/4 q_i^4

mode q1 at 1.0 MHz
mode q2 at 1.6 MHz
mode q3 at 2.6 MHz           # = 1.0 MHz + 1.6 MHz

param kappa                  # three-wave coupling, 1/(m s^2)
for i in 1..3: param beta[i]

potential: kappa * q1*q2*q3
for i in 1..3: potential: beta[i]/4 * q[i]^4
