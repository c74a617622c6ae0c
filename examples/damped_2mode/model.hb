# Two modes of a resonator whose damping grows with the amplitude (clamping losses, friction,
# thermoelastic nonlinearity): Duffing terms, a dispersive coupling, nonlinear damping of q1 and
# the damping of q1 that the motion of q2 induces.
#
#   q1'' + (w1/Q1) q1' + w1^2 q1 + beta1 q1^3 + g12 q1 q2^2 + eta1 q1^2 q1' + eta12 q2^2 q1' = F1(t)
#   q2'' + (w2/Q2) q2' + w2^2 q2 + beta2 q2^3 + g12 q1^2 q2 = F2(t)

mode q1 at 1.0 MHz
mode q2 at 1.6 MHz

param beta1, beta2, g12      # 1/(m^2 s^2)
param eta1, eta12            # 1/(m^2 s): d(q1) is the velocity of q1

potential: beta1/4*q1^4 + beta2/4*q2^4 + g12/2*q1^2*q2^2
eom q1 += eta1*q1^2*d(q1) + eta12*q2^2*d(q1)
