//! Numbers for the summary: time to reach a target error, read off a measured curve.

/// The time at which the error curve `points` (time, relMSE), in order of time, first reaches
/// `target` (points sorted by time first: a render may overrun its budget), interpolating linearly in log–log between the bracketing measurements (errors of
/// Monte Carlo renders fall as a power of time, a straight line there). `None` when no
/// measurement reaches the target; the first point's time when it already does.
pub fn time_to_target(points: &[(f64, f64)], target: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = points
        .iter()
        .copied()
        .filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite())
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let first = pts.first()?;
    if first.1 <= target {
        return Some(first.0);
    }
    for w in pts.windows(2) {
        let ((t0, e0), (t1, e1)) = (w[0], w[1]);
        if e1 <= target {
            let (lt0, lt1, le0, le1) = (t0.ln(), t1.ln(), e0.ln(), e1.ln());
            let f = if le1 == le0 {
                1.0
            } else {
                (target.ln() - le0) / (le1 - le0)
            };
            return Some((lt0 + f * (lt1 - lt0)).exp());
        }
    }
    None
}

/// For an unbiased estimator that has not reached `target` within its measurements: when it
/// would, if its own error keeps falling as 1/t from the last measurement. `floor` is the
/// reference's own relMSE, which every measured error includes and no estimator can go below:
/// the estimator's part of the last error is `e − floor`. `None` when the target is below
/// twice the floor (the reference could not tell) or the curve has no usable point.
pub fn extrapolated_time(points: &[(f64, f64)], target: f64, floor: f64) -> Option<f64> {
    let (t, e) = points
        .iter()
        .copied()
        .filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite())
        .max_by(|a, b| a.0.total_cmp(&b.0))?;
    if !(target >= 2.0 * floor) || e <= target {
        return None;
    }
    Some(t * (e - floor) / (target - floor))
}

/// Formats seconds compactly (`-` for none).
pub fn secs(s: Option<f64>) -> String {
    match s {
        Some(s) if s.is_finite() => format!("{s:.2}"),
        _ => "-".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extrapolation_of_an_unbiased_curve() {
        // relMSE 0.1 at 10 s over a floor of 0.001: 0.01 is reached at 10 × 0.099 / 0.009 = 110 s.
        let t = extrapolated_time(&[(2.0, 0.5), (10.0, 0.1)], 0.01, 0.001).unwrap();
        assert!((t - 110.0).abs() < 1e-9, "{t}");
        // Not for a target the curve reached or one the reference cannot resolve.
        assert_eq!(extrapolated_time(&[(10.0, 0.1)], 0.2, 0.0), None);
        assert_eq!(extrapolated_time(&[(10.0, 0.1)], 0.01, 0.006), None);
        // At twice the floor (where the summary raises a lower target to): 10 × 0.095 / 0.005.
        let t = extrapolated_time(&[(10.0, 0.1)], 0.01, 0.005).unwrap();
        assert!((t - 190.0).abs() < 1e-9, "{t}");
    }

    #[test]
    fn time_to_target_on_a_known_curve() {
        // relMSE = 0.1 / t: exact on a log–log line.
        let curve: Vec<(f64, f64)> = [1.0, 2.0, 4.0, 8.0].iter().map(|&t| (t, 0.1 / t)).collect();
        let t = time_to_target(&curve, 0.1 / 3.0).unwrap();
        assert!((t - 3.0).abs() < 1e-9, "{t}");
        assert_eq!(time_to_target(&curve, 0.5), Some(1.0));
        assert_eq!(time_to_target(&curve, 0.001), None);
        // A curve that goes up before it comes down still finds the first crossing.
        let bumpy = [(1.0, 0.2), (2.0, 0.3), (4.0, 0.05)];
        let t = time_to_target(&bumpy, 0.1).unwrap();
        assert!(t > 2.0 && t < 4.0);
        assert_eq!(time_to_target(&[], 0.1), None);
    }
}
