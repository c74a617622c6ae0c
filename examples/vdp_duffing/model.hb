# A driven van der Pol–Duffing oscillator: negative linear damping (mu < -w0/Q) makes it
# self-oscillate, the nonlinear damping eta q^2 q' bounds the oscillation, beta q^3 shifts it:
#
#   q'' + (w0/Q + mu) q' + w0^2 q + beta q^3 + eta q^2 q' = F cos(2 pi f t).
#
# A drive far enough from resonance leaves the self-oscillation beside it (a quasi-periodic
# response); nearer, the driven response quenches it. Between the two: Hopf points, and from
# each the limit-cycle branch (docs/exploring.md).
mode q1, f = 1 kHz, Q = 10000
param mu, beta, eta
eom q1 += mu*d(q1) + beta*q1^3 + eta*q1^2*d(q1)
