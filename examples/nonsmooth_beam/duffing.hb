# Where discover starts on the stand-in (README): the Duffing term alone.
mode q1 at 1 MHz
param beta1
potential: beta1/4*q1^4
