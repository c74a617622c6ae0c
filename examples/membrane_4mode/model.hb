# Four modes of a membrane with two resonant mixing processes (issue 10's "new user" model):
#
#   U = alpha q1^2 q2 + kappa q1 q3 q4 + sum_i beta_i/4 q_i^4
#
# alpha q1^2 q2 is resonant because f2 ~ 2 f1: driving q1 near f1 pumps q2 at twice the tone
# (and a drive of q2 near 2 f1 modulates q1 parametrically). kappa q1 q3 q4 is resonant because
# f4 ~ f1 + f3: driving q1 and q3 makes q4 respond at the sum of their tones. q2 and q4 need no
# tone of their own to be seen.

mode q1 at 1.0 MHz
mode q2 at 2.0004 MHz         # ~ 2 f1 (5 linewidths above)
mode q3 at 1.5 MHz
mode q4 at 2.5005 MHz         # ~ f1 + f3 (6 linewidths above)

param alpha                   # quadratic coupling, 1/(m s^2)
param kappa                   # three-mode coupling, 1/(m s^2)
for i in 1..4: param beta[i]  # Duffing, 1/(m^2 s^2)

potential: alpha * q1^2 * q2
potential: kappa * q1 * q3 * q4
for i in 1..4: potential: beta[i]/4 * q[i]^4
