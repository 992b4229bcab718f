//! The smoother's 7 × 7 algebra on plain arrays ([`super::smoother`]).
//!
//! nalgebra's static and dynamic matrices of this size each brought their own
//! multiplication, LU and inverse code into the page's module (about 10 KB gzipped, more
//! than the threaded module's budget had left); these few loops do what the filter
//! needs: products, transposes and a Gauss-Jordan inverse with partial pivoting.
//!
//! Each is `#[inline]`, so the optimiser decides by the build's opt-level: the page's
//! first-paint module, built for size, keeps them out of line (90 bytes more gzipped
//! than with `#[inline(never)]`; forced inline at every use, the products alone grew it
//! by kilobytes); the analysis module and the CLI, built for speed, inline all but the
//! product (4.6 kB more for the analysis module). Out of line, a 7 × 7 operand
//! (392 bytes) passed or returned by value is copied through memory on every call,
//! which WebAssembly does with bulk-memory calls into the engine: in Node's profile of
//! the Pixel 6a drive (a transition and an update each second of 87 minutes)
//! `Cov::mul`, `Cov::zeros` and `Cov::identity` took a fifth of the pipeline, and
//! inlined the pipeline took 85-88 ms against 95-100 (`pdr_pipeline_files`, best of 15,
//! three rounds, 2026-12-06).

use std::ops::{Add, AddAssign, Index, IndexMut, Mul, Sub};

/// The smoother's state dimension.
pub(super) const DIM: usize = 7;

/// A state (or a row of a measurement matrix).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct State(pub(super) [f64; DIM]);

/// A covariance, a transition or a gain, row-major.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Cov(pub(super) [[f64; DIM]; DIM]);

impl State {
    #[inline]
    pub(super) fn zeros() -> State {
        State([0.0; DIM])
    }

    #[inline]
    pub(super) fn dot(&self, other: &State) -> f64 {
        self.0.iter().zip(&other.0).map(|(a, b)| a * b).sum()
    }

    /// `self · otherᵀ`, a matrix of rank one.
    #[inline]
    pub(super) fn outer(&self, other: &State) -> Cov {
        let mut out = Cov::zeros();
        for (row, a) in out.0.iter_mut().zip(&self.0) {
            for (cell, b) in row.iter_mut().zip(&other.0) {
                *cell = a * b;
            }
        }
        out
    }

    #[inline]
    pub(super) fn scaled(&self, factor: f64) -> State {
        State(self.0.map(|value| value * factor))
    }
}

impl Cov {
    #[inline]
    pub(super) fn zeros() -> Cov {
        Cov([[0.0; DIM]; DIM])
    }

    #[inline]
    pub(super) fn identity() -> Cov {
        let mut out = Cov::zeros();
        for (i, row) in out.0.iter_mut().enumerate() {
            row[i] = 1.0;
        }
        out
    }

    #[inline]
    pub(super) fn transpose(&self) -> Cov {
        let mut out = Cov::zeros();
        for (i, row) in self.0.iter().enumerate() {
            for (j, value) in row.iter().enumerate() {
                out.0[j][i] = *value;
            }
        }
        out
    }

    /// `self · other`, where `other` is a state.
    #[inline]
    pub(super) fn times(&self, other: &State) -> State {
        State(std::array::from_fn(|i| State(self.0[i]).dot(other)))
    }

    #[inline]
    pub(super) fn scaled(&self, factor: f64) -> Cov {
        Cov(self.0.map(|row| row.map(|value| value * factor)))
    }

    /// `(self + selfᵀ) / 2`.
    #[inline]
    pub(super) fn symmetric(&self) -> Cov {
        (*self + self.transpose()).scaled(0.5)
    }

    /// The inverse by Gauss-Jordan elimination with partial pivoting; `None` when a
    /// pivot is below `1e-300` (singular to working precision).
    #[inline]
    pub(super) fn try_inverse(&self) -> Option<Cov> {
        let mut a = self.0;
        let mut inverse = Cov::identity().0;
        for column in 0..DIM {
            let pivot =
                (column..DIM).max_by(|&r, &s| a[r][column].abs().total_cmp(&a[s][column].abs()))?;
            let size = a[pivot][column].abs();
            if size.is_nan() || size <= 1e-300 {
                return None;
            }
            a.swap(column, pivot);
            inverse.swap(column, pivot);
            let scale = 1.0 / a[column][column];
            for k in 0..DIM {
                a[column][k] *= scale;
                inverse[column][k] *= scale;
            }
            for row in 0..DIM {
                if row == column {
                    continue;
                }
                let factor = a[row][column];
                if factor == 0.0 {
                    continue;
                }
                for k in 0..DIM {
                    a[row][k] -= factor * a[column][k];
                    inverse[row][k] -= factor * inverse[column][k];
                }
            }
        }
        Some(Cov(inverse))
    }
}

impl Index<usize> for State {
    type Output = f64;
    fn index(&self, i: usize) -> &f64 {
        &self.0[i]
    }
}

impl IndexMut<usize> for State {
    fn index_mut(&mut self, i: usize) -> &mut f64 {
        &mut self.0[i]
    }
}

impl Index<(usize, usize)> for Cov {
    type Output = f64;
    fn index(&self, (i, j): (usize, usize)) -> &f64 {
        &self.0[i][j]
    }
}

impl IndexMut<(usize, usize)> for Cov {
    fn index_mut(&mut self, (i, j): (usize, usize)) -> &mut f64 {
        &mut self.0[i][j]
    }
}

impl Add for State {
    type Output = State;
    #[inline]
    fn add(self, other: State) -> State {
        State(std::array::from_fn(|i| self.0[i] + other.0[i]))
    }
}

impl Sub for State {
    type Output = State;
    #[inline]
    fn sub(self, other: State) -> State {
        State(std::array::from_fn(|i| self.0[i] - other.0[i]))
    }
}

impl AddAssign for State {
    #[inline]
    fn add_assign(&mut self, other: State) {
        *self = *self + other;
    }
}

impl Add for Cov {
    type Output = Cov;
    #[inline]
    fn add(self, other: Cov) -> Cov {
        Cov(std::array::from_fn(|i| {
            std::array::from_fn(|j| self.0[i][j] + other.0[i][j])
        }))
    }
}

impl Sub for Cov {
    type Output = Cov;
    #[inline]
    fn sub(self, other: Cov) -> Cov {
        Cov(std::array::from_fn(|i| {
            std::array::from_fn(|j| self.0[i][j] - other.0[i][j])
        }))
    }
}

impl Mul for Cov {
    type Output = Cov;
    #[inline]
    fn mul(self, other: Cov) -> Cov {
        let mut out = Cov::zeros();
        for i in 0..DIM {
            for k in 0..DIM {
                let a = self.0[i][k];
                if a == 0.0 {
                    continue;
                }
                for j in 0..DIM {
                    out.0[i][j] += a * other.0[k][j];
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inverse_undoes_a_covariance_and_refuses_a_singular_one() {
        let mut m = Cov::identity().scaled(2.0);
        for i in 0..DIM {
            for j in 0..DIM {
                m[(i, j)] +=
                    0.1 * ((i * 3 + j * 5) % 7) as f64 / (1.0 + (i as f64 - j as f64).abs());
            }
        }
        let m = m.symmetric();
        let product = m * m.try_inverse().expect("invertible");
        for i in 0..DIM {
            for j in 0..DIM {
                let expected = if i == j { 1.0 } else { 0.0 };
                assert!((product[(i, j)] - expected).abs() < 1e-12, "{product:?}");
            }
        }
        let mut singular = Cov::identity();
        singular[(3, 3)] = 0.0;
        assert_eq!(singular.try_inverse(), None);
    }

    #[test]
    fn products_and_outer_products_agree_with_their_definitions() {
        let a = State(std::array::from_fn(|i| i as f64 + 1.0));
        let b = State(std::array::from_fn(|i| 2.0 - i as f64));
        let outer = a.outer(&b);
        assert_eq!(outer[(2, 3)], -3.0);
        assert_eq!(outer.times(&a), a.scaled(b.dot(&a)));
        assert_eq!((outer * Cov::identity()), outer);
        assert_eq!(outer.transpose()[(3, 2)], outer[(2, 3)]);
    }
}
