# A stand-in for the held-back lock-in measurement of issue 36 (not in the repository): one mode
# that softens in proportion to its amplitude (|q|q stiffness) and whose damping grows like
# the amplitude (quadratic drag |q'|q'), beside Duffing stiffness and q^2 q' damping. The
# coefficients are unknowns that enter linearly; abs(...) takes one mode or one velocity.
mode q1 at 1 MHz
param beta1, eta1, kappa1, drag1
potential: beta1/4*q1^4
eom q1 += eta1*q1^2*d(q1) + kappa1*abs(q1)*q1 + drag1*abs(d(q1))*d(q1)
