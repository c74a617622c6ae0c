# Si3N4 nanostring (support length 50 um): the first two flexural modes.
#
#   q1'' + (w1/Q1) q1' + w1^2 q1 + beta1 q1^3 + g12 q1 q2^2 = F1(t)
#   q2'' + (w2/Q2) q2' + w2^2 q2 + beta2 q2^3 + g12 q1^2 q2 = F2(t)
#
# Both modes are Duffing oscillators, coupled dispersively through the tension the string gains
# when it bends: U = beta1/4 q1^4 + beta2/4 q2^4 + g12/2 q1^2 q2^2.

mode q1 at 207.58 kHz        # nominal resonance; f1 and Q1 are identified from data
mode q2 at 415.84 kHz

param beta1, beta2           # Duffing coefficients, 1/(m^2 s^2)
param g12                    # dispersive coupling, 1/(m^2 s^2)

potential: beta1/4*q1^4 + beta2/4*q2^4
potential: g12/2*q1^2*q2^2
