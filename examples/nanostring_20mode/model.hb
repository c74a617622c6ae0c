# Twenty flexural modes of a nanostring (issue 40, item 3): twenty Duffing terms and all 190
# pairwise dispersive couplings, 210 unknown nonlinear parameters. Modes near n·207.58 kHz,
# slightly stiffer above: f_n = n·207.58 kHz·(1 + 0.002 n²), as in nanostring_10mode.

mode q1 at 207.995 kHz
mode q2 at 418.481 kHz
mode q3 at 633.949 kHz
mode q4 at 856.890 kHz
mode q5 at 1089.795 kHz
mode q6 at 1335.155 kHz
mode q7 at 1595.460 kHz
mode q8 at 1873.202 kHz
mode q9 at 2170.872 kHz
mode q10 at 2490.960 kHz
mode q11 at 2835.958 kHz
mode q12 at 3208.356 kHz
mode q13 at 3610.647 kHz
mode q14 at 4045.319 kHz
mode q15 at 4514.865 kHz
mode q16 at 5021.775 kHz
mode q17 at 5568.541 kHz
mode q18 at 6157.653 kHz
mode q19 at 6791.602 kHz
mode q20 at 7472.880 kHz

for i in 1..20 {
    param beta[i]                  # beta1 ... beta20, 1/(m^2 s^2)
    potential: beta[i]/4 * q[i]^4
}

for i<j in 1..20 {
    param g[i,j] >= 0              # g1_2 ... g19_20: tension coupling is stiffening
    potential: g[i,j]/2 * q[i]^2 * q[j]^2
}
