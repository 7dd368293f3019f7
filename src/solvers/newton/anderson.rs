//! Anderson acceleration of the outer rounds (Walker & Ni, "Anderson acceleration for
//! fixed-point iterations", 2011, type II): the rounds are a fixed-point map λ̄ ↦ Φ(λ̄) (the
//! answer with proximal centre and friction bounds λ̄); with the active set settled the map is
//! affine and the accelerated centre `Φ(λ̄_k) − ΔG γ`, `γ = argmin ‖f_k − ΔF γ‖` over the last
//! few differences of `f = Φ(λ̄) − λ̄` and of Φ, converges like GMRES instead of linearly.
//! Away from that regime (the active set still changing, redundant rows making the differences
//! nearly dependent) the extrapolation can stall: a round whose `‖f‖` did not shrink restarts
//! the history and takes the plain step (a safeguard in the manner of Fang & Saad, 2009).

/// The history of the last rounds.
#[derive(Default)]
pub(super) struct Anderson {
    /// Differences ΔF and ΔG, `depth` columns of n entries each (ring).
    delta_f: Vec<Vec<f64>>,
    delta_g: Vec<Vec<f64>>,
    /// f and g of the last round, and ‖f‖ then.
    last_f: Vec<f64>,
    last_norm: f64,
    last_g: Vec<f64>,
    /// Columns in use, and where the next goes.
    used: usize,
    next: usize,
    has_last: bool,
    /// Scratch: f of this round, the normal equations and γ.
    f: Vec<f64>,
    gram: Vec<f64>,
    rhs: Vec<f64>,
}

impl Anderson {
    /// Forgets the history; keeps `depth` columns of `n` entries.
    pub(super) fn reset(&mut self, n: usize, depth: usize) {
        self.delta_f.resize_with(depth, Vec::new);
        self.delta_g.resize_with(depth, Vec::new);
        for v in self.delta_f.iter_mut().chain(self.delta_g.iter_mut()) {
            v.clear();
            v.resize(n, 0.0);
        }
        for v in [&mut self.last_f, &mut self.last_g, &mut self.f] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.used = 0;
        self.next = 0;
        self.has_last = false;
    }

    /// Given the centre x and the round's answer g = Φ(x), writes the next centre into x.
    pub(super) fn next_centre(&mut self, x: &mut [f64], g: &[f64]) {
        let depth = self.delta_f.len();
        let mut norm = 0.0;
        for ((f, g), x) in self.f.iter_mut().zip(g).zip(x.iter()) {
            *f = g - x;
            norm += *f * *f;
        }
        if self.has_last && norm >= 0.98 * self.last_norm {
            // Not shrinking: forget the history, take the plain step from here.
            self.used = 0;
            self.next = 0;
            self.has_last = false;
        }
        self.last_norm = norm;
        if self.has_last && depth > 0 {
            let column = self.next;
            for ((d, f), last) in self.delta_f[column].iter_mut().zip(&self.f).zip(&self.last_f) {
                *d = f - last;
            }
            for ((d, g), last) in self.delta_g[column].iter_mut().zip(g).zip(&self.last_g) {
                *d = g - last;
            }
            self.next = (self.next + 1) % depth;
            self.used = (self.used + 1).min(depth);
        }
        self.last_f.copy_from_slice(&self.f);
        self.last_g.copy_from_slice(g);
        self.has_last = true;
        x.copy_from_slice(g);
        let m = self.used;
        if m == 0 {
            return;
        }
        // Normal equations (ΔFᵀ ΔF + δ I) γ = ΔFᵀ f, δ a relative 1e-12 of the trace.
        self.gram.clear();
        self.gram.resize(m * m, 0.0);
        self.rhs.clear();
        self.rhs.resize(m, 0.0);
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
        for a in 0..m {
            for b in a..m {
                let v = dot(&self.delta_f[a], &self.delta_f[b]);
                self.gram[a * m + b] = v;
                self.gram[b * m + a] = v;
            }
            self.rhs[a] = dot(&self.delta_f[a], &self.f);
        }
        let trace: f64 = (0..m).map(|a| self.gram[a * m + a]).sum();
        if trace.is_nan() || trace <= 0.0 {
            return;
        }
        for a in 0..m {
            self.gram[a * m + a] += 1e-12 * trace;
        }
        // Cholesky of the small m × m system in place.
        for j in 0..m {
            let mut d = self.gram[j * m + j];
            for k in 0..j {
                d -= self.gram[j * m + k] * self.gram[j * m + k];
            }
            if d.is_nan() || d <= 0.0 {
                return;
            }
            let d = d.sqrt();
            self.gram[j * m + j] = d;
            for i in j + 1..m {
                let mut s = self.gram[i * m + j];
                for k in 0..j {
                    s -= self.gram[i * m + k] * self.gram[j * m + k];
                }
                self.gram[i * m + j] = s / d;
            }
        }
        for i in 0..m {
            let mut s = self.rhs[i];
            for k in 0..i {
                s -= self.gram[i * m + k] * self.rhs[k];
            }
            self.rhs[i] = s / self.gram[i * m + i];
        }
        for i in (0..m).rev() {
            let mut s = self.rhs[i];
            for k in i + 1..m {
                s -= self.gram[k * m + i] * self.rhs[k];
            }
            self.rhs[i] = s / self.gram[i * m + i];
        }
        for a in 0..m {
            let gamma = self.rhs[a];
            for (x, dg) in x.iter_mut().zip(&self.delta_g[a]) {
                *x -= gamma * dg;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On an affine contraction x ↦ M x + c in 3 dimensions, three differences make the
    /// accelerated iteration exact where the plain one converges at rate 0.9.
    #[test]
    fn affine_map_converges_in_a_few_rounds() {
        let m = [[0.9, 0.05, 0.0], [0.0, 0.8, 0.1], [0.02, 0.0, 0.85]];
        let c = [1.0, -2.0, 0.5];
        let map = |x: &[f64]| -> Vec<f64> {
            (0..3).map(|i| (0..3).map(|j| m[i][j] * x[j]).sum::<f64>() + c[i]).collect()
        };
        let mut anderson = Anderson::default();
        anderson.reset(3, 5);
        let mut x = vec![0.0; 3];
        let mut plain = vec![0.0; 3];
        for _ in 0..6 {
            let g = map(&x);
            anderson.next_centre(&mut x, &g);
            plain = map(&plain);
        }
        let g = map(&x);
        let error: f64 = (0..3).map(|i| (g[i] - x[i]).abs()).fold(0.0, f64::max);
        let plain_error: f64 = (0..3).map(|i| (map(&plain)[i] - plain[i]).abs()).fold(0.0, f64::max);
        assert!(error < 1e-9, "accelerated fixed-point residual {error}");
        assert!(plain_error > 1e-2, "plain iteration residual {plain_error}");
    }
}
