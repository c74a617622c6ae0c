# Si3N4 nanostring: the first five flexural modes, each a Duffing oscillator, every pair coupled
# dispersively:
#
#   U = sum_i beta_i/4 q_i^4 + sum_{i<j} g_ij/2 q_i^2 q_j^2
#
# so the equation of q_i holds beta_i q_i^3 and g_ij q_i q_j^2 for every j != i.

# A string's modes sit near multiples of the fundamental (slightly stiffer above).
mode q1 at 207.58 kHz
mode q2 at 415.84 kHz
mode q3 at 624.3 kHz
mode q4 at 833.2 kHz
mode q5 at 1042.6 kHz

for i in 1..5 {
    param beta[i]                          # beta1 ... beta5
    potential: beta[i]/4 * q[i]^4
}

for i<j in 1..5 {
    param g[i,j] >= 0                      # g12, g13, ..., g45: tension coupling is stiffening
    potential: g[i,j]/2 * q[i]^2 * q[j]^2
}
