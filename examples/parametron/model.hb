# The parametron: a Duffing resonator whose spring constant the pump modulates,
#
#   q'' + (w0/Q) q' + w0^2 q + beta q^3 + lambda pump(t) q = 0,   pump(t) = P cos(2 pi f_p t).
#
# Pumped near twice its resonance it oscillates at f_p/2 in one of two opposite phases once
# |lambda P|/2 exceeds the damping (docs/exploring.md).
mode q1, f = 1 kHz, Q = 1000
param beta, lambda
eom q1 += beta*q1^3 + lambda*pump*q1
