//! Broad phase: sweep and prune on the axis along which the boxes spread most. The sorted order
//! is kept between steps, so re-sorting is an insertion sort over a nearly sorted list (linear in
//! the number of objects when they move little); half-spaces and other unbounded boxes are kept
//! out of the sweep and tested against every bounded box.

use parry3d_f64::bounding_volume::Aabb;

/// Boxes larger than this (m) on some axis are treated as unbounded.
const UNBOUNDED_EXTENT: f64 = 1e7;

/// The broad phase's state, reused across steps.
#[derive(Clone, Debug, Default)]
pub(crate) struct SweepAndPrune {
    order: Vec<u32>,
    unbounded: Vec<u32>,
    axis: usize,
    count: usize,
}

fn overlaps(a: &Aabb, b: &Aabb) -> bool {
    a.mins.x <= b.maxs.x
        && b.mins.x <= a.maxs.x
        && a.mins.y <= b.maxs.y
        && b.mins.y <= a.maxs.y
        && a.mins.z <= b.maxs.z
        && b.mins.z <= a.maxs.z
}

fn is_unbounded(a: &Aabb) -> bool {
    let e = a.maxs - a.mins;
    !(e.x < UNBOUNDED_EXTENT && e.y < UNBOUNDED_EXTENT && e.z < UNBOUNDED_EXTENT)
}

fn lower(a: &Aabb, axis: usize) -> f64 {
    a.mins[axis]
}

impl SweepAndPrune {
    /// Calls `emit(i, j)` once for every pair of boxes that overlap (i ≠ j, in no particular
    /// order within the pair) and for which `wanted(i, j)` holds. `aabbs[i]` is collider i's box.
    pub fn pairs(
        &mut self,
        aabbs: &[Aabb],
        mut wanted: impl FnMut(usize, usize) -> bool,
        mut emit: impl FnMut(usize, usize),
    ) {
        if aabbs.len() != self.count {
            self.rebuild(aabbs);
        }
        let axis = spread_axis(aabbs, &self.order);
        if axis != self.axis {
            self.axis = axis;
            self.order.sort_unstable_by(|&a, &b| {
                lower(&aabbs[a as usize], axis).total_cmp(&lower(&aabbs[b as usize], axis)).then(a.cmp(&b))
            });
        } else {
            insertion_sort(&mut self.order, |a, b| {
                let (ka, kb) = (lower(&aabbs[a as usize], axis), lower(&aabbs[b as usize], axis));
                ka > kb || (ka == kb && a > b)
            });
        }
        for (k, &a) in self.order.iter().enumerate() {
            let box_a = &aabbs[a as usize];
            for &b in &self.order[k + 1..] {
                let box_b = &aabbs[b as usize];
                if box_b.mins[axis] > box_a.maxs[axis] {
                    break;
                }
                if overlaps(box_a, box_b) && wanted(a as usize, b as usize) {
                    emit(a as usize, b as usize);
                }
            }
        }
        for &u in &self.unbounded {
            for b in 0..aabbs.len() {
                let is_other_unbounded =
                    b as u32 == u || (self.unbounded.contains(&(b as u32)) && b as u32 <= u);
                if !is_other_unbounded && overlaps(&aabbs[u as usize], &aabbs[b]) && wanted(u as usize, b) {
                    emit(u as usize, b);
                }
            }
        }
    }

    /// Re-partitions bounded and unbounded boxes (when colliders are added or removed).
    fn rebuild(&mut self, aabbs: &[Aabb]) {
        self.count = aabbs.len();
        self.order.clear();
        self.unbounded.clear();
        for (i, a) in aabbs.iter().enumerate() {
            if is_unbounded(a) {
                self.unbounded.push(i as u32);
            } else {
                self.order.push(i as u32);
            }
        }
        self.axis = usize::MAX;
    }

    /// Forces a re-partition at the next call (a box may have become unbounded or bounded).
    pub fn invalidate(&mut self) {
        self.count = usize::MAX;
    }
}

/// The axis along which the centres of the bounded boxes vary most.
fn spread_axis(aabbs: &[Aabb], order: &[u32]) -> usize {
    if order.len() < 2 {
        return 0;
    }
    let (mut sum, mut sum_sq) = ([0.0; 3], [0.0; 3]);
    for &i in order {
        let a = &aabbs[i as usize];
        for k in 0..3 {
            let c = 0.5 * (a.mins[k] + a.maxs[k]);
            sum[k] += c;
            sum_sq[k] += c * c;
        }
    }
    let n = order.len() as f64;
    let var = |k: usize| sum_sq[k] / n - (sum[k] / n).powi(2);
    (0..3).max_by(|&a, &b| var(a).total_cmp(&var(b))).unwrap_or(0)
}

/// Stable in-place insertion sort: linear on nearly sorted input, never allocates.
fn insertion_sort(v: &mut [u32], greater: impl Fn(u32, u32) -> bool) {
    for i in 1..v.len() {
        let x = v[i];
        let mut j = i;
        while j > 0 && greater(v[j - 1], x) {
            v[j] = v[j - 1];
            j -= 1;
        }
        v[j] = x;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use parry3d_f64::math::Vector;
    use rand::{Rng, SeedableRng};

    fn brute(aabbs: &[Aabb]) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        for i in 0..aabbs.len() {
            for j in i + 1..aabbs.len() {
                if overlaps(&aabbs[i], &aabbs[j]) {
                    out.push((i, j));
                }
            }
        }
        out
    }

    #[test]
    fn finds_exactly_the_overlapping_pairs_across_steps() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut centres: Vec<Vector> = (0..300)
            .map(|_| {
                Vector::new(
                    rng.random_range(-5.0..5.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(0.0..1.0),
                )
            })
            .collect();
        let mut sap = SweepAndPrune::default();
        for step in 0..5 {
            let mut aabbs: Vec<Aabb> =
                centres.iter().map(|c| Aabb::new(*c - Vector::splat(0.3), *c + Vector::splat(0.3))).collect();
            aabbs.push(Aabb::new(Vector::splat(-1e12), Vector::new(1e12, 1e12, 0.0)));
            let mut got = Vec::new();
            sap.pairs(&aabbs, |_, _| true, |a, b| got.push((a.min(b), a.max(b))));
            got.sort_unstable();
            assert_eq!(got, brute(&aabbs), "step {step}");
            for c in &mut centres {
                *c += Vector::new(rng.random_range(-0.05..0.05), 0.0, rng.random_range(-0.05..0.05));
            }
        }
    }
}
