//! The gyroscope's bias from how its turns carry "down" along: over windows of
//! [`BIAS_WINDOW_S`], the down at a window's end against the down at its start turned
//! by the gyroscope. A bias `b` turns the propagated down away by
//! `(M·b) × d_b` with `M = ∫ R(t_b←s) ds` (the window's turns, `R(t_b←s)` the body's
//! rotation from `s` to the window's end), so the windows' residuals give `b` by linear
//! least squares, with a prior of a raw MEMS gyroscope's bias
//! ([`crate::attitude::RAW_BIAS_SIGMA_RADPS`]) weighed against the residuals' own size
//! (the down's error). A bias along down is not seen while down stays along it; the
//! prior keeps it near zero then.
//!
//! This is the integral term of Mahony et al.'s complementary filter (2008, IEEE TAC
//! 53(5)), solved once over the log rather than fed back sample by sample: the
//! estimate of down it is measured against is the two-pass one of [`super::down`], which
//! has no first-order bias lag.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::MAX_GYRO_GAP_S;
use crate::io::recording::Stream;

/// The gyroscope's bias (rad/s, body axes, after `gyro_scale` and `known_bias_radps`)
/// that makes its turns carry `fused` down along best: over windows of
/// [`BIAS_WINDOW_S`], the down at a window's end against the down at its start turned
/// by the gyroscope, `r = d_b − R·d_a ≈ (M·b) × d_b` with `M = ∫ R(t_b←s) ds`, solved by
/// least squares over the windows.
pub fn gyro_bias_radps(
    fused: &Stream<Vector3<f64>>,
    gyro: &Stream<Vector3<f64>>,
    gyro_scale: f64,
    known_bias_radps: Vector3<f64>,
) -> Option<Vector3<f64>> {
    let n = fused.len().min(fused.t_s.len());
    let down_at = |idx: usize| fused.values.get(idx).and_then(|f| (-f).try_normalize(1e-9));
    let mut normal = Matrix3::<f64>::zeros();
    let mut rhs = Vector3::<f64>::zeros();
    let (mut sum_sq_residual, mut n_windows) = (0.0, 0usize);
    let mut start = 0usize;
    while start + 1 < n {
        let Some(d_a) = down_at(start) else {
            start += 1;
            continue;
        };
        let t_a = fused.t_s[start];
        let mut turn = Rotation3::identity();
        let mut integral = Matrix3::<f64>::zeros();
        let mut idx = start;
        let mut broken = false;
        while idx + 1 < n && fused.t_s[idx] - t_a < BIAS_WINDOW_S {
            let (t0, t1) = (fused.t_s[idx], fused.t_s[idx + 1]);
            let dt_s = t1 - t0;
            let Some(rate) = gyro.interpolate_at(0.5 * (t0 + t1), MAX_GYRO_GAP_S) else {
                broken = true;
                break;
            };
            if !(dt_s > 0.0 && dt_s <= MAX_GYRO_GAP_S) {
                broken = true;
                break;
            }
            let rate = rate * gyro_scale - known_bias_radps;
            // ∫ R(s←t_a)ᵀ ds over the step (the mean of its two ends' turns).
            let next = Rotation3::new(-rate * dt_s) * turn;
            integral += (turn.matrix() + next.matrix()).transpose() * (0.5 * dt_s);
            turn = next;
            idx += 1;
        }
        let end = idx;
        if broken || end == start {
            start = end.max(start + 1);
            continue;
        }
        if let Some(d_b) = down_at(end) {
            let m = turn.matrix() * integral;
            let residual = d_b - turn * d_a;
            let jacobian = -d_b.cross_matrix() * m;
            normal += jacobian.transpose() * jacobian;
            rhs += jacobian.transpose() * residual;
            sum_sq_residual += residual.norm_squared();
            n_windows += 1;
        }
        start = end;
    }
    if n_windows < 3 {
        return None;
    }
    // A prior of the bias's size (a raw MEMS gyroscope's, 1σ per axis), weighed against
    // the windows' residuals (the down's own error): where the turns do not show an
    // axis's bias, it stays near zero.
    let residual_variance = sum_sq_residual / (2.0 * n_windows as f64);
    let ridge = residual_variance / crate::attitude::RAW_BIAS_SIGMA_RADPS.powi(2);
    if ridge.is_nan() || ridge <= 0.0 {
        return None;
    }
    (normal + Matrix3::identity() * ridge)
        .cholesky()
        .map(|cholesky| cholesky.solve(&rhs))
        .filter(|bias| bias.iter().all(|v| v.is_finite()))
}

/// The window (s) over which the gyroscope's bias is seen: long enough that a bias's
/// turn (2.6° for 0.003 rad/s) stands above the down's own error, which is what limits
/// the estimate while an arm swings. On the independent generator's swinging phone the
/// exported calibration was within 1.3 × the true one's heading error in 18 of 20 seeds
/// against 14 with 3 s windows (`tests/independent.rs`). On TYREX NoDist_Texting the
/// estimate is 9 mrad/s from the bias the motion capture shows, against 14 with 3 s
/// (`tests/real_data.rs`); on the swinging and pocket trials it is further from it than
/// zero, so on real phones this is the bias that makes down consistent with the
/// gyroscope, not the gyroscope's bias alone.
pub const BIAS_WINDOW_S: f64 = 15.0;

#[cfg(test)]
mod tests {
    use super::*;

    /// Down (as the specific force gravity gives) and the gyroscope's rates of a body
    /// turning about changing axes for `duration_s` at 100 Hz, the gyroscope reading
    /// `bias` on top.
    fn tumbling(
        duration_s: f64,
        bias: Vector3<f64>,
    ) -> (Stream<Vector3<f64>>, Stream<Vector3<f64>>) {
        let (mut fused, mut gyro) = (Stream::default(), Stream::default());
        let mut down = Vector3::new(0.1, -0.2, 1.0).normalize();
        let rate_at = |t_s: f64| {
            Vector3::new(
                0.5 * (0.7 * t_s).sin(),
                0.4 * (0.5 * t_s).cos(),
                0.3 * (0.3 * t_s).sin(),
            )
        };
        let dt_s = 0.01;
        for idx in 0..(duration_s / dt_s) as usize {
            let t_s = idx as f64 * dt_s;
            fused.push(t_s, -down * 9.81);
            gyro.push(t_s, rate_at(t_s) + bias);
            // The rate at the step's midpoint, as the estimator reads it.
            down = Rotation3::new(-rate_at(t_s + 0.5 * dt_s) * dt_s) * down;
        }
        (fused, gyro)
    }

    /// Found as `refine` finds it, each round removing what the last found: the first
    /// round's is short by 10-30 % (a 15 s window turns the bias's error by up to 7°,
    /// where the linear model's residuals weigh the prior up).
    #[test]
    fn a_tumbling_body_s_bias_is_found() {
        let bias = Vector3::new(0.008, -0.006, 0.004);
        let (fused, gyro) = tumbling(120.0, bias);
        let mut found = Vector3::zeros();
        for _ in 0..3 {
            found += gyro_bias_radps(&fused, &gyro, 1.0, found).expect("a bias");
        }
        assert!((found - bias).norm() < 2e-4, "{found:?} against {bias:?}");
        // Already removed, nothing is left.
        let left = gyro_bias_radps(&fused, &gyro, 1.0, bias).expect("a bias");
        assert!(left.norm() < 2e-4, "{left:?}");
    }

    #[test]
    fn too_short_a_log_shows_no_bias() {
        let (fused, gyro) = tumbling(5.0, Vector3::new(0.01, 0.0, 0.0));
        assert_eq!(gyro_bias_radps(&fused, &gyro, 1.0, Vector3::zeros()), None);
    }
}
