# The Brake-Reuss beam (examples/import/brb.toml, ../shared/realdata/brb): one mode near 80 Hz
# of a beam with a bolted lap joint. Duffing + eta q1^2 d(q1) leaves 15 % misfit; the joint
# softens in proportion to the amplitude, which kappa1*abs(q1)*q1 writes (issue 36):
# misfit 7.6 %, see docs/judging-a-model.md. Coulomb friction (mu1*sign(d(q1)) or
# mu1*tanh(d(q1)/1e-3)) is not determined by these data.
mode q1 at 80.2 Hz
param beta1, eta1, kappa1
potential: beta1/4*q1^4
eom q1 += eta1*q1^2*d(q1) + kappa1*abs(q1)*q1
