# Ten flexural modes of a nanostring (issue 22's stress case): ten Duffing terms and all 45
# pairwise dispersive couplings, 55 unknown nonlinear parameters. Modes near n·207.58 kHz,
# slightly stiffer above: f_n = n·207.58 kHz·(1 + 0.002 n²).

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

for i in 1..10 {
    param beta[i]                  # beta1 ... beta10, 1/(m^2 s^2)
    potential: beta[i]/4 * q[i]^4
}

for i<j in 1..10 {
    param g[i,j] >= 0              # g1_2 ... g9_10: tension coupling is stiffening
    potential: g[i,j]/2 * q[i]^2 * q[j]^2
}
