# The MFLI beam (examples/import/mfli_beam.toml): one softening mode with amplitude-dependent
# damping, Duffing + eta * q1^2 * d(q1). Amplitudes in volts (no sensor calibration).
mode q1 at 42.77 Hz
param beta1, eta1
potential: beta1/4*q1^4
eom q1 += eta1*q1^2*d(q1)
