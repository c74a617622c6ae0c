//! Two-tone frequency sweeps: the centre `c` of a tone pair `c ± Δ/2` (fixed spacing `Δ`) is
//! swept by natural-parameter continuation of the multi-tone harmonic balance ([`HbSolver`]),
//! separately upwards and downwards, with a stability verdict per point and the jumps each
//! direction shows.
//!
//! The lattice is a fixed set of tone combinations `k` (pair coefficients `a, b`, extra-tone
//! coefficients `e_j`), so its line `k` sits at `f_k(c) = (a+b)·c + (b−a)·Δ/2 + Σ_j e_j g_j` and
//! the amplitudes of consecutive centres map one to one. The set is chosen once for the whole
//! range: every combination of order `Σ|k| ≤ K` (odd orders only for odd models) that comes
//! within `window_rel · f_n` of a resonance `f_n` somewhere in the range, plus the tones and the
//! reported lines.
//!
//! Stepping: the centres of a grid `c_start + i·h₀` (`h₀ = range / points`) are always visited,
//! so an up- and a down-sweep can be compared point by point. A step is halved when Newton fails
//! or the state changes by more than `max_rel_change` (relative to the largest amplitude); at the
//! minimum step a jump is recorded and the solver lands on the state Newton reached, or, when
//! Newton failed, on the state a fresh drive ramp reaches at that centre.

use super::Step;
use crate::lattice::{enumerate, LINE_TOL_HZ};
use crate::{Excitation, HbSettings, HbSolver, NumericModel, SimError, SteadyState};
use num_complex::Complex64;

/// Settings of a two-tone sweep ([`sweep_two_tone`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TwoToneSettings {
    /// One end of the swept centre range, Hz.
    pub c_start_hz: f64,
    /// The other end, Hz (either order; both directions are swept).
    pub c_end_hz: f64,
    /// Spacing `Δ` of the pair, Hz (tones at `c − Δ/2` and `c + Δ/2`).
    pub spacing_hz: f64,
    /// Complex force (N/kg, peak) of the lower tone on each mode.
    pub force_low: Vec<Complex64>,
    /// Complex force (N/kg, peak) of the upper tone on each mode.
    pub force_high: Vec<Complex64>,
    /// Extra tones at fixed frequencies (e.g. a probe on another mode), Hz.
    pub extra_tones_hz: Vec<f64>,
    /// `extra_force[n][j]`: force of extra tone `j` on mode `n`, N/kg (empty when no extra tone).
    pub extra_force: Vec<Vec<Complex64>>,
    /// Reported lines as offsets from the centre, Hz (default: `−3Δ/2, −Δ/2, Δ/2, 3Δ/2`, the
    /// tones and the first sidebands, when empty).
    pub lines_offset_hz: Vec<f64>,
    /// Number of grid steps over the range (`h₀ = range / points`).
    pub points: usize,
    /// Smallest step, as a fraction of `h₀`, before a jump is recorded.
    pub min_step_rel: f64,
    /// Largest accepted change of the state between consecutive points, relative to the largest
    /// amplitude.
    pub max_rel_change: f64,
    /// Harmonic-balance settings: lattice order, window and harmonics, Newton tolerance, ramp
    /// (for the start and the landings after jumps). `lattice.extra_hz` is ignored.
    pub hb: HbSettings,
}

impl Default for TwoToneSettings {
    fn default() -> Self {
        Self {
            c_start_hz: 0.0,
            c_end_hz: 0.0,
            spacing_hz: 20.0,
            force_low: Vec::new(),
            force_high: Vec::new(),
            extra_tones_hz: Vec::new(),
            extra_force: Vec::new(),
            lines_offset_hz: Vec::new(),
            points: 400,
            min_step_rel: 1e-3,
            max_rel_change: 0.25,
            hb: HbSettings::default(),
        }
    }
}

/// One point of a two-tone response curve.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoTonePoint {
    /// Centre of the pair, Hz.
    pub centre_hz: f64,
    /// `amplitudes[n][l]`: complex amplitude (m, peak) of mode `n` at its own line
    /// [`TwoToneSweep::mode_lines`]`[n][l]` (for a mode near the pair: `centre_hz +
    /// lines_offset_hz[l]`).
    pub amplitudes: Vec<Vec<Complex64>>,
    /// Whether the steady state is stable (Hill's method, [`HbSolver::stability`]).
    pub stable: bool,
    /// Largest growth rate of the linearised slow flow, 1/s (negative when stable).
    pub growth_rate: f64,
    /// Relative residual `max |R| / max |F|` of the state.
    pub residual: f64,
}

/// A jump of a sweep: continuation could not follow the branch beyond `from_hz`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwoToneJump {
    /// Centre of the last point on the branch left, Hz.
    pub from_hz: f64,
    /// Centre where the state landed, Hz.
    pub to_hz: f64,
    /// Index in [`TwoToneCurve::points`] of the landing point.
    pub index: usize,
    /// `max |X_after − X_before| / max |X|` over every mode and lattice line.
    pub rel_change: f64,
}

/// How a sweep direction ended.
#[derive(Debug, Clone, PartialEq)]
pub enum TwoToneStatus {
    /// The whole range was swept.
    Complete,
    /// The sweep stopped early at `at_hz` (the points before are valid).
    Stopped {
        /// Centre where it stopped, Hz.
        at_hz: f64,
        /// What happened and what to try.
        why: String,
    },
}

/// One sweep direction.
#[derive(Debug, Clone, PartialEq)]
pub struct TwoToneCurve {
    /// `true`: increasing centre.
    pub up: bool,
    /// Points in sweep order.
    pub points: Vec<TwoTonePoint>,
    /// Jumps in sweep order.
    pub jumps: Vec<TwoToneJump>,
    /// Complete or stopped.
    pub status: TwoToneStatus,
}

/// A line a mode is reported at: `f = centre_factor · c + offset_hz` for the pair's centre `c`.
#[derive(Debug, Clone, PartialEq)]
pub struct ModeLine {
    /// Multiple of the centre (1 near the pair, 2 near its second harmonic, 0 for an extra tone).
    pub centre_factor: f64,
    /// Offset, Hz.
    pub offset_hz: f64,
    /// The combination of the low tone `fa`, the high tone `fb` and the extra tones `g1`, `g2`,
    /// ... (ASCII, e.g. `2fa-fb`, `fa+fb`, `g1`), or `c+15Hz` for a reported offset that no
    /// combination reaches.
    pub label: String,
}

impl ModeLine {
    /// The line's frequency at centre `c`, Hz.
    pub fn hz(&self, centre_hz: f64) -> f64 {
        self.centre_factor * centre_hz + self.offset_hz
    }
}

/// Result of [`sweep_two_tone`].
#[derive(Debug, Clone, PartialEq)]
pub struct TwoToneSweep {
    /// The reported lines of the modes near the pair, offsets from the centre, Hz.
    pub lines_offset_hz: Vec<f64>,
    /// `mode_lines[n]`: the lines mode `n` is reported at, those of [`TwoToneCurve::points`]'
    /// `amplitudes[n]`. A mode whose resonance the pair sweeps past gets `lines_offset_hz`; any
    /// other mode gets the lattice lines that come near its own resonance in the range (the
    /// mixing products that reach it), lowest intermodulation orders first.
    pub mode_lines: Vec<Vec<ModeLine>>,
    /// Number of lattice lines (the same at every centre).
    pub lattice_lines: usize,
    /// Increasing centre.
    pub up: TwoToneCurve,
    /// Decreasing centre.
    pub down: TwoToneCurve,
}

/// A lattice line: `f(c) = s·c + off`, and the combination `(a, b, e_1, ...)` of the low tone,
/// the high tone and the extra tones that makes it (empty for a reported offset no combination
/// reaches).
#[derive(Debug, Clone)]
struct Line {
    s: f64,
    off: f64,
    k: Vec<i64>,
}

impl Line {
    fn order(&self) -> i64 {
        if self.k.is_empty() {
            i64::MAX
        } else {
            self.k.iter().map(|x| x.abs()).sum()
        }
    }

    /// `2fa-fb`, `fa+g1`, ... (`c+15Hz` without a combination).
    fn label(&self) -> String {
        if self.k.is_empty() {
            return format!("c{:+}Hz", self.off);
        }
        // The one formatter of combinations (harmonid_spectral): positive terms first.
        let labels: Vec<String> = (0..self.k.len())
            .map(|i| match i {
                0 => "fa".to_string(),
                1 => "fb".to_string(),
                j => format!("g{}", j - 1),
            })
            .collect();
        let k: Vec<i32> = self
            .k
            .iter()
            .map(|&x| i32::try_from(x).unwrap_or(i32::MAX))
            .collect();
        harmonid_spectral::Combination::from_coeffs(&k).compact_with(&labels)
    }
}

struct Problem<'a> {
    model: &'a NumericModel,
    set: &'a TwoToneSettings,
    lines: Vec<Line>,
    /// `report[n]`: lattice index of each reported line of mode `n`.
    report: Vec<Vec<usize>>,
}

/// A solved point in line order: `x[n][i]` at line `i`.
struct Solved {
    x: Vec<Vec<Complex64>>,
    converged: bool,
    residual: f64,
    stable: bool,
    growth: f64,
}

impl Problem<'_> {
    /// The solver at centre `c` and the permutation line → sorted lattice index.
    fn solver(&self, c: f64) -> Result<(HbSolver, Vec<usize>), SimError> {
        let set = self.set;
        let nm = self.model.n_modes();
        let f: Vec<f64> = self.lines.iter().map(|l| l.s * c + l.off).collect();
        let mut order: Vec<usize> = (0..f.len()).collect();
        order.sort_by(|&a, &b| f[a].total_cmp(&f[b]));
        let mut perm = vec![0; f.len()];
        for (p, &i) in order.iter().enumerate() {
            perm[i] = p;
        }
        let lattice: Vec<f64> = order.iter().map(|&i| f[i]).collect();
        if lattice[0] <= LINE_TOL_HZ || lattice.windows(2).any(|w| w[1] - w[0] <= LINE_TOL_HZ) {
            return Err(SimError::CoincidentLines { centre_hz: c });
        }
        let mut tones = vec![c - 0.5 * set.spacing_hz, c + 0.5 * set.spacing_hz];
        tones.extend_from_slice(&set.extra_tones_hz);
        let force = (0..nm)
            .map(|n| {
                let mut r = vec![set.force_low[n], set.force_high[n]];
                if !set.extra_tones_hz.is_empty() {
                    r.extend_from_slice(&set.extra_force[n]);
                }
                r
            })
            .collect();
        let drive = Excitation {
            pumps: Vec::new(),
            tones_hz: tones,
            force,
        };
        Ok((HbSolver::with_lattice(self.model, &drive, lattice)?, perm))
    }

    /// Solves at `c` from `start` (line order) or by a fresh drive ramp.
    fn solve(&self, c: f64, start: Option<&[Vec<Complex64>]>) -> Result<Solved, SimError> {
        let (mut solver, perm) = self.solver(c)?;
        let st: SteadyState = match start {
            Some(x) => {
                let init: Vec<Vec<Complex64>> = x
                    .iter()
                    .map(|row| {
                        let mut r = vec![Complex64::new(0.0, 0.0); row.len()];
                        for (i, &z) in row.iter().enumerate() {
                            r[perm[i]] = z;
                        }
                        r
                    })
                    .collect();
                solver.solve_from(&init, &self.set.hb)
            }
            None => solver.solve(&self.set.hb),
        };
        let x: Vec<Vec<Complex64>> = st
            .amplitudes
            .iter()
            .map(|row| perm.iter().map(|&p| row[p]).collect())
            .collect();
        let converged = st.converged();
        let (stable, growth) = if converged {
            let s = solver.stability(&st)?;
            (s.stable, s.growth_rate)
        } else {
            (false, f64::MAX)
        };
        Ok(Solved {
            x,
            converged,
            residual: st.residual,
            stable,
            growth,
        })
    }

    /// Where the state lands at `c` when continuation from `cur` fails at the minimum step:
    /// the first converged and stable state among Newton's own result `s`, a fresh drive ramp,
    /// and Newton from `cur` scaled by a few factors and phase turns (a drive ramp cannot pass a fold in the
    /// drive, e.g. just beyond the down-sweep jump of a hardening mode). Unstable states are
    /// only kept when nothing stable is found.
    fn land(&self, c: f64, cur: &[Vec<Complex64>], s: Solved) -> Result<Solved, SimError> {
        if s.converged && s.stable {
            return Ok(s);
        }
        let mut fallback = if s.converged { Some(s) } else { None };
        let ramp = self.solve(c, None)?;
        if ramp.converged && ramp.stable {
            return Ok(ramp);
        }
        if ramp.converged && fallback.is_none() {
            fallback = Some(ramp);
        }
        let scales = [2.0, 0.5, 4.0, 0.25, 8.0, 0.1, 16.0];
        let turns = [0.0, -0.25, 0.25, 0.5];
        for (k, t) in turns
            .iter()
            .flat_map(|&t| scales.iter().map(move |&k| (k, t)))
        {
            let z = Complex64::from_polar(k, std::f64::consts::TAU * t);
            let start: Vec<Vec<Complex64>> = cur
                .iter()
                .map(|r| r.iter().map(|x| x * z).collect())
                .collect();
            let t = self.solve(c, Some(&start))?;
            if t.converged && t.stable {
                return Ok(t);
            }
            if t.converged && fallback.is_none() {
                fallback = Some(t);
            }
        }
        Ok(fallback.unwrap_or(Solved {
            x: cur.to_vec(),
            converged: false,
            residual: f64::MAX,
            stable: false,
            growth: f64::MAX,
        }))
    }

    fn point(&self, c: f64, s: &Solved) -> TwoTonePoint {
        TwoTonePoint {
            centre_hz: c,
            amplitudes: s
                .x
                .iter()
                .zip(&self.report)
                .map(|(row, rep)| rep.iter().map(|&i| row[i]).collect())
                .collect(),
            stable: s.stable,
            growth_rate: s.growth,
            residual: s.residual,
        }
    }

    /// One direction of the sweep: [`CentreSteps`] from one end of the range to the other.
    fn sweep(&self, up: bool) -> Result<TwoToneCurve, SimError> {
        let mut curve = TwoToneCurve {
            up,
            points: Vec::new(),
            jumps: Vec::new(),
            status: TwoToneStatus::Complete,
        };
        let mut steps = CentreSteps::new(self.set, up);
        let first = self.solve(steps.c, None)?;
        if !first.converged {
            curve.status = TwoToneStatus::Stopped {
                at_hz: steps.c,
                why: format!(
                    "the drive ramp did not converge at the start (residual {:.2e}); try a smaller force or a wider lattice",
                    first.residual
                ),
            };
            return Ok(curve);
        }
        curve.points.push(self.point(steps.c, &first));
        steps.cur = first.x;
        loop {
            let (step, point) = steps.step(self)?;
            match step {
                Step::Reached => return Ok(curve),
                Step::Advanced => {}
                Step::Jump { at } => curve.jumps.push(TwoToneJump {
                    from_hz: at,
                    to_hz: steps.c,
                    index: curve.points.len(),
                    rel_change: steps.jump_change,
                }),
                Step::Stuck | Step::Fold { .. } => {
                    curve.status = TwoToneStatus::Stopped {
                        at_hz: steps.c_failed,
                        why: format!(
                            "continuation failed and neither a fresh drive ramp nor Newton from scaled states converged (residual {:.2e}); try a smaller force, a wider lattice (order, window) or more points",
                            steps.residual_failed
                        ),
                    };
                    return Ok(curve);
                }
            }
            curve.points.extend(point);
        }
    }
}

/// Natural-parameter continuation in the centre frequency (see the module docs): the grid
/// of centres every direction visits, the step between them, and the branch's last states.
struct CentreSteps {
    up: bool,
    lo: f64,
    hi: f64,
    /// Grid intervals, the grid spacing `h₀` and the smallest step.
    points: usize,
    h0: f64,
    h_min: f64,
    /// Centres closer than this are the same.
    tol_c: f64,
    /// The current centre, the next grid index, the step.
    c: f64,
    next: usize,
    h: f64,
    /// The state at `c` (line order) and the previous one on the same branch, for the secant.
    cur: Vec<Vec<Complex64>>,
    prev: Option<(f64, Vec<Vec<Complex64>>)>,
    /// After a [`Step::Jump`]: the relative change of the state.
    jump_change: f64,
    /// After a [`Step::Stuck`]: where, and the residual of the best attempt.
    c_failed: f64,
    residual_failed: f64,
}

impl CentreSteps {
    fn new(set: &TwoToneSettings, up: bool) -> Self {
        let (lo, hi) = (
            set.c_start_hz.min(set.c_end_hz),
            set.c_start_hz.max(set.c_end_hz),
        );
        let points = set.points.max(1);
        let h0 = (hi - lo) / points as f64;
        Self {
            up,
            lo,
            hi,
            points,
            h0,
            h_min: h0 * set.min_step_rel,
            tol_c: 1e-12 * hi.abs().max(1.0),
            c: if up { lo } else { hi },
            next: 1,
            h: h0,
            cur: Vec::new(),
            prev: None,
            jump_change: 0.0,
            c_failed: f64::NAN,
            residual_failed: f64::NAN,
        }
    }

    /// Centre of grid point `i`.
    fn grid(&self, i: usize) -> f64 {
        match (i >= self.points, self.up) {
            (true, true) => self.hi,
            (true, false) => self.lo,
            (false, true) => self.lo + self.h0 * i as f64,
            (false, false) => self.hi - self.h0 * i as f64,
        }
    }

    /// One step towards the next grid centre, halved (down to the minimum step) while Newton
    /// fails or the state changes by more than `max_rel_change`; at the minimum step the state
    /// lands ([`Problem::land`]): [`Step::Jump`] when it changed that much, else
    /// [`Step::Advanced`]; [`Step::Stuck`] when nothing converged. The point reached comes
    /// with the step. [`Step::Reached`] past the last grid centre.
    fn step(&mut self, p: &Problem) -> Result<(Step, Option<TwoTonePoint>), SimError> {
        let set = p.set;
        let sign = if self.up { 1.0 } else { -1.0 };
        loop {
            if self.next > self.points || self.h0 <= 0.0 {
                return Ok((Step::Reached, None));
            }
            let c = self.c;
            let target = self.grid(self.next);
            let dist = (target - c).abs();
            let h_eff = self.h.min(dist);
            let c_new = if h_eff >= dist - self.tol_c {
                target
            } else {
                c + sign * h_eff
            };
            // Secant predictor from the previous point on the same branch.
            let guess: Vec<Vec<Complex64>> = match &self.prev {
                Some((cp, xp)) if (c - cp).abs() > 0.0 => {
                    let t = (c_new - c) / (c - cp);
                    self.cur
                        .iter()
                        .zip(xp)
                        .map(|(a, b)| a.iter().zip(b).map(|(a, b)| a + (a - b) * t).collect())
                        .collect()
                }
                _ => self.cur.clone(),
            };
            let s = p.solve(c_new, Some(&guess))?;
            let change = rel_change(&self.cur, &s.x);
            let accept = s.converged && change <= set.max_rel_change;
            if !accept && h_eff > self.h_min * 1.000001 {
                self.h = (h_eff * 0.5).max(self.h_min);
                continue;
            }
            if c_new == target {
                self.next += 1;
            }
            if accept {
                let point = p.point(c_new, &s);
                self.prev = Some((c, std::mem::replace(&mut self.cur, s.x)));
                self.h = (self.h * 2.0).min(self.h0);
                self.c = c_new;
                return Ok((Step::Advanced, Some(point)));
            }
            // At the minimum step: the state lands where the slow flow takes it.
            let land = p.land(c_new, &self.cur, s)?;
            if !land.converged {
                self.c_failed = c_new;
                self.residual_failed = land.residual;
                return Ok((Step::Stuck, None));
            }
            let ch = rel_change(&self.cur, &land.x);
            let jumped = ch > set.max_rel_change;
            if jumped {
                self.jump_change = ch;
                self.prev = None;
            }
            self.h = self.h0;
            let point = p.point(c_new, &land);
            self.cur = land.x;
            self.c = c_new;
            let step = if jumped {
                Step::Jump { at: c }
            } else {
                Step::Advanced
            };
            return Ok((step, Some(point)));
        }
    }
}

/// `max |a − b| / max(|a|, |b|)` over all entries (0 when both vanish).
fn rel_change(a: &[Vec<Complex64>], b: &[Vec<Complex64>]) -> f64 {
    let mut d: f64 = 0.0;
    let mut m: f64 = 0.0;
    for (ra, rb) in a.iter().zip(b) {
        for (x, y) in ra.iter().zip(rb) {
            d = d.max((x - y).norm());
            m = m.max(x.norm()).max(y.norm());
        }
    }
    if m > 0.0 {
        d / m
    } else {
        0.0
    }
}

/// Chooses the fixed combination set (see the module docs).
fn choose_lines(model: &NumericModel, set: &TwoToneSettings, offsets: &[f64]) -> Vec<Line> {
    let (lo, hi) = (
        set.c_start_hz.min(set.c_end_hz),
        set.c_start_hz.max(set.c_end_hz),
    );
    let odd_only = model.terms().iter().all(|t| t.degree() % 2 == 1);
    let dmax = model.max_degree().max(1) as i64;
    let half = 0.5 * set.spacing_hz;
    let nd = 2 + set.extra_tones_hz.len();
    let unit = |d: usize| {
        let mut k = vec![0i64; nd];
        k[d] = 1;
        k
    };
    let mut lines = vec![
        Line {
            s: 1.0,
            off: -half,
            k: unit(0),
        },
        Line {
            s: 1.0,
            off: half,
            k: unit(1),
        },
    ];
    lines.extend(set.extra_tones_hz.iter().enumerate().map(|(j, &g)| Line {
        s: 0.0,
        off: g,
        k: unit(2 + j),
    }));
    let order = set.hb.lattice.order as i64;
    let w = set.hb.lattice.window_rel;
    let mut k = vec![0i64; nd];
    enumerate(&mut k, 0, order, &mut |k| {
        let ord: i64 = k.iter().map(|x| x.abs()).sum();
        if ord == 0 || (odd_only && ord % 2 == 0) {
            return;
        }
        let s = (k[0] + k[1]) as f64;
        let off = (k[1] - k[0]) as f64 * half
            + k[2..]
                .iter()
                .zip(&set.extra_tones_hz)
                .map(|(&e, &g)| e as f64 * g)
                .sum::<f64>();
        let (f0, f1) = (s * lo + off, s * hi + off);
        let (fmin, fmax) = (f0.min(f1), f0.max(f1));
        if fmin <= 10.0 * LINE_TOL_HZ {
            return;
        }
        let near = model
            .f_hz
            .iter()
            .any(|&fnn| fmax >= fnn * (1.0 - w) && fmin <= fnn * (1.0 + w));
        if near || (set.hb.lattice.harmonics && ord <= dmax) {
            lines.push(Line {
                s,
                off,
                k: k.to_vec(),
            });
        }
    });
    // Reported offsets no combination reaches are kept as lines of their own.
    lines.extend(offsets.iter().map(|&o| Line {
        s: 1.0,
        off: o,
        k: Vec::new(),
    }));
    // One line per frequency, made by its lowest-order combination.
    let mut out: Vec<Line> = Vec::with_capacity(lines.len());
    for l in lines {
        match out
            .iter_mut()
            .find(|m| m.s == l.s && (m.off - l.off).abs() <= LINE_TOL_HZ)
        {
            Some(m) if l.order() < m.order() => *m = l,
            Some(_) => {}
            None => out.push(l),
        }
    }
    out
}

/// The lines each mode is reported at (see [`TwoToneSweep::mode_lines`]): lattice indices.
/// A mode is near the pair when its resonance lies within `window_rel · f_n` of a tone somewhere
/// in the range; otherwise its lines are the lattice lines within `window_rel · f_n` of `f_n`
/// somewhere in the range, sorted by order and offset, at most [`MAX_MODE_LINES`].
fn mode_lines(
    model: &NumericModel,
    set: &TwoToneSettings,
    lines: &[Line],
    offsets: &[f64],
) -> Vec<Vec<usize>> {
    let (lo, hi) = (
        set.c_start_hz.min(set.c_end_hz),
        set.c_start_hz.max(set.c_end_hz),
    );
    let half = 0.5 * set.spacing_hz;
    let w = set.hb.lattice.window_rel;
    let reach = |l: &Line, f_n: f64| {
        let (f0, f1) = (l.s * lo + l.off, l.s * hi + l.off);
        f0.max(f1) >= f_n * (1.0 - w) && f0.min(f1) <= f_n * (1.0 + w)
    };
    model
        .f_hz
        .iter()
        .map(|&f_n| {
            let near_pair = reach(
                &Line {
                    s: 1.0,
                    off: -half,
                    k: Vec::new(),
                },
                f_n,
            ) || reach(
                &Line {
                    s: 1.0,
                    off: half,
                    k: Vec::new(),
                },
                f_n,
            );
            if near_pair {
                return offsets
                    .iter()
                    .map(|&o| {
                        lines
                            .iter()
                            .position(|l| l.s == 1.0 && (l.off - o).abs() <= LINE_TOL_HZ)
                            .unwrap_or(0)
                    })
                    .collect();
            }
            let mut own: Vec<usize> = (0..lines.len())
                .filter(|&i| !lines[i].k.is_empty() && reach(&lines[i], f_n))
                .collect();
            own.sort_by(|&a, &b| {
                let (la, lb) = (&lines[a], &lines[b]);
                la.order()
                    .cmp(&lb.order())
                    .then(la.s.total_cmp(&lb.s))
                    .then(la.off.total_cmp(&lb.off))
            });
            own.truncate(MAX_MODE_LINES);
            own.sort_by(|&a, &b| {
                let (la, lb) = (&lines[a], &lines[b]);
                la.s.total_cmp(&lb.s).then(la.off.total_cmp(&lb.off))
            });
            own
        })
        .collect()
}

/// Most lines reported for a mode away from the pair.
pub const MAX_MODE_LINES: usize = 6;

/// Sweeps the centre of a tone pair up and down (see the module docs). Errors: bad settings
/// (non-finite or non-positive range/spacing, force shapes), lattice set-up failures. Newton and
/// ramp failures during the sweep end that direction with [`TwoToneStatus::Stopped`] and keep
/// the points before; no amplitude is ever NaN.
pub fn sweep_two_tone(
    model: &NumericModel,
    settings: &TwoToneSettings,
) -> Result<TwoToneSweep, SimError> {
    let nm = model.n_modes();
    let bad = |what: &str, value: f64, why: &str| SimError::BadValue {
        what: what.into(),
        value,
        why: why.into(),
    };
    for (what, v) in [
        ("the sweep start", settings.c_start_hz),
        ("the sweep end", settings.c_end_hz),
        ("the tone spacing", settings.spacing_hz),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(bad(what, v, "must be a finite positive frequency in Hz"));
        }
    }
    let lo = settings.c_start_hz.min(settings.c_end_hz);
    if lo - 0.5 * settings.spacing_hz <= 0.0 {
        return Err(bad(
            "the lower tone at the sweep start",
            lo - 0.5 * settings.spacing_hz,
            "must stay positive: use a spacing below twice the lowest centre",
        ));
    }
    if !(settings.min_step_rel > 0.0 && settings.min_step_rel < 1.0) {
        return Err(bad(
            "min_step_rel",
            settings.min_step_rel,
            "must lie in (0, 1)",
        ));
    }
    if settings.max_rel_change.is_nan() || settings.max_rel_change <= 0.0 {
        return Err(bad(
            "max_rel_change",
            settings.max_rel_change,
            "must be positive",
        ));
    }
    if settings.force_low.len() != nm || settings.force_high.len() != nm {
        return Err(SimError::Length {
            what: "the pair's forces",
            found: settings.force_low.len().min(settings.force_high.len()),
            expected: nm,
            per: "one per mode".into(),
        });
    }
    if !settings.extra_tones_hz.is_empty()
        && (settings.extra_force.len() != nm
            || settings
                .extra_force
                .iter()
                .any(|r| r.len() != settings.extra_tones_hz.len()))
    {
        return Err(SimError::Length {
            what: "the extra tones' forces",
            found: settings.extra_force.iter().map(Vec::len).sum(),
            expected: nm * settings.extra_tones_hz.len(),
            per: format!("{nm} modes × {} tones", settings.extra_tones_hz.len()),
        });
    }
    let offsets: Vec<f64> = if settings.lines_offset_hz.is_empty() {
        let d = settings.spacing_hz;
        vec![-1.5 * d, -0.5 * d, 0.5 * d, 1.5 * d]
    } else {
        settings.lines_offset_hz.clone()
    };
    if let Some(&o) = offsets.iter().find(|o| !o.is_finite()) {
        return Err(bad("a reported line offset", o, "must be finite"));
    }
    let lines = choose_lines(model, settings, &offsets);
    let report = mode_lines(model, settings, &lines, &offsets);
    let described = report
        .iter()
        .map(|rep| {
            rep.iter()
                .map(|&i| ModeLine {
                    centre_factor: lines[i].s,
                    offset_hz: lines[i].off,
                    label: lines[i].label(),
                })
                .collect()
        })
        .collect();
    let p = Problem {
        model,
        set: settings,
        lines,
        report,
    };
    let up = p.sweep(true)?;
    let down = p.sweep(false)?;
    Ok(TwoToneSweep {
        lines_offset_hz: offsets,
        mode_lines: described,
        lattice_lines: p.lines.len(),
        up,
        down,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{linear_response, Term};
    use std::f64::consts::TAU;

    /// Mode 2 near twice mode 1, driven through `c·q1²` in its equation: swept around mode 1,
    /// mode 2 is reported at its own lines 2fa, fa+fb, 2fb, and at weak drive its amplitude there
    /// is the closed form `−c·X_a·X_b·(½ if a = b) / (ω2² − ω² + iγ2·ω)` with `X` mode 1's
    /// linear response.
    #[test]
    fn a_mode_at_twice_the_frequency_is_reported_at_its_own_lines() {
        let (f1, f2, q1, q2, c) = (1000.0, 2010.0, 200.0, 300.0, 1.0e9);
        let model = NumericModel::new(
            vec!["q1".into(), "q2".into()],
            vec![f1, f2],
            vec![q1, q2],
            vec![Term {
                eq: 1,
                coef: c,
                factors: vec![(0, 2)],
            }],
        )
        .expect("model");
        let force = 1e-3;
        let set = TwoToneSettings {
            c_start_hz: 995.0,
            c_end_hz: 1005.0,
            spacing_hz: 2.0,
            force_low: vec![Complex64::new(force, 0.0), Complex64::new(0.0, 0.0)],
            force_high: vec![Complex64::new(force, 0.0), Complex64::new(0.0, 0.0)],
            points: 10,
            ..TwoToneSettings::default()
        };
        let r = sweep_two_tone(&model, &set).expect("sweep");
        assert_eq!(r.up.status, TwoToneStatus::Complete);
        let labels: Vec<&str> = r.mode_lines[1].iter().map(|l| l.label.as_str()).collect();
        for want in ["2fa", "fa+fb", "2fb"] {
            assert!(
                labels.contains(&want),
                "mode 2's lines {labels:?} miss {want}"
            );
        }
        // Mode 1 keeps the pair's lines.
        assert_eq!(r.mode_lines[0].len(), r.lines_offset_hz.len());
        assert_eq!(r.mode_lines[0][1].label, "fa");
        let (w1, g1) = (TAU * f1, TAU * f1 / q1);
        let (w2, g2) = (TAU * f2, TAU * f2 / q2);
        let mut worst: f64 = 0.0;
        for p in &r.up.points {
            let c0 = p.centre_hz;
            let xa = linear_response(w1, g1, c0 - 1.0, Complex64::new(force, 0.0));
            let xb = linear_response(w1, g1, c0 + 1.0, Complex64::new(force, 0.0));
            for (l, line) in r.mode_lines[1].iter().enumerate() {
                let prod = match line.label.as_str() {
                    "2fa" => 0.5 * xa * xa,
                    "fa+fb" => xa * xb,
                    "2fb" => 0.5 * xb * xb,
                    _ => continue,
                };
                let want = linear_response(w2, g2, line.hz(c0), -c * prod);
                let got = p.amplitudes[1][l];
                worst = worst.max((got - want).norm() / want.norm());
            }
        }
        assert!(
            worst < 1e-3,
            "worst relative deviation from the closed form {worst:.2e}"
        );
    }

    #[test]
    fn labels_name_the_combination() {
        let l = Line {
            s: 1.0,
            off: -15.0,
            k: vec![2, -1, 0],
        };
        assert_eq!(l.label(), "2fa-fb");
        let l = Line {
            s: 0.0,
            off: 5.0,
            k: vec![1, -1, 1],
        };
        assert_eq!(l.label(), "fa+g1-fb");
        let l = Line {
            s: 1.0,
            off: 25.0,
            k: vec![-1, 2, 0],
        };
        assert_eq!(l.label(), "2fb-fa");
    }
}
