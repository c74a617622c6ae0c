# A beam that softens in proportion to its amplitude and whose damping grows like its velocity
# (issue 36): |q|q stiffness and quadratic drag |q'|q', beside a Duffing term. The kind of
# device the held-back lock-in measurement is (frequency shift proportional to the amplitude,
# not its square). abs(...) takes one mode or one velocity; the coefficients are unknowns
# that enter linearly, as any other term's.
mode q1 at 10 kHz
param kappa1, drag1, beta1
eom q1 += kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1)
potential: beta1/4*q1^4
