# The MFLI beam (examples/import/mfli_beam.toml) with the model issue 36 asks of the held-back
# lock-in measurement: Duffing, nonlinear damping eta1*q1^2*d(q1), a stiffness proportional to
# the amplitude kappa1*abs(q1)*q1 and quadratic drag drag1*abs(d(q1))*d(q1). Amplitudes in
# volts (no sensor calibration). Fitted with --gain-per-mode --background drive --error-floor;
# numbers in docs/judging-a-model.md.
mode q1 at 42.77 Hz
param beta1, eta1, kappa1, drag1
potential: beta1/4*q1^4
eom q1 += eta1*q1^2*d(q1) + kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1)
