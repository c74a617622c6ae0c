# Two Duffing modes 4 Hz apart with a dispersive coupling: each mode's frequency shifts with
# the other's amplitude squared,
#
#   U = b1/4 q1^4 + b2/4 q2^4 + g/2 q1^2 q2^2.
mode q1, f = 1 kHz, Q = 1000
mode q2, f = 1.004 kHz, Q = 800
param b1, b2, g
potential: b1/4*q1^4 + b2/4*q2^4 + g/2*q1^2*q2^2
