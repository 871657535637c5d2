//! The test's thresholds from its false-alarm rate (docs/maths.md, "Failure detection"): the
//! upper quantiles of the χ² distribution, in `f64` and computed once, at configuration.

/// `erfc⁻¹(p)` for `p` in (0, 1]: bisection on libm's `erfc`, which decreases on `[0, ∞)`
/// (`x ≥ 0` since `p ≤ 1`). 200 halvings of `[0, 40]` reach the last bit.
fn erfc_inverse(p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0_f64, 40.0_f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if libm::erfc(mid) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The upper standard normal quantile `z` with `P(Z > z) = p`, `p` in (0, ½]:
/// `z = √2 erfc⁻¹(2p)`.
pub fn normal_upper(p: f64) -> f64 {
    core::f64::consts::SQRT_2 * erfc_inverse(2.0 * p)
}

/// `P(χ² > x)` with `dof` degrees of freedom, in closed form (Abramowitz and Stegun 26.4.4
/// and 26.4.5): for even `dof = 2n`, `e^{−x/2} Σ_{i<n} (x/2)^i / i!`; for odd `dof`,
/// `erfc(√(x/2)) + √(2x/π) e^{−x/2} Σ_{i<(dof−1)/2} x^i / (3·5···(2i+1))`.
///
/// Past [`DIRECT_DOF`] degrees of freedom the terms are summed from their logarithms, so that
/// `e^{−x/2}` and the growing powers (each beyond `f64`'s range for a band's thousands of
/// degrees) never meet as `0 · ∞`: each term is a probability, at most 1.
pub fn chi2_survival(dof: usize, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let dof = dof.max(1);
    if dof > DIRECT_DOF {
        return chi2_survival_logs(dof, x);
    }
    let e = libm::exp(-0.5 * x);
    if dof.is_multiple_of(2) {
        let (mut term, mut sum) = (1.0, 0.0);
        for i in 0..dof / 2 {
            if i > 0 {
                term *= 0.5 * x / i as f64;
            }
            sum += term;
        }
        e * sum
    } else {
        let (mut term, mut sum) = (1.0, 0.0);
        for i in 0..(dof - 1) / 2 {
            if i > 0 {
                term *= x / (2 * i + 1) as f64;
            }
            sum += term;
        }
        libm::erfc(libm::sqrt(0.5 * x)) + libm::sqrt(2.0 * x / core::f64::consts::PI) * e * sum
    }
}

/// The degrees of freedom up to which [`chi2_survival`] multiplies its terms directly (the
/// detector's and the single samples' tests, whose thresholds keep their bits).
pub const DIRECT_DOF: usize = 200;

/// [`chi2_survival`]'s sums for many degrees of freedom, each term `e^{ln term}`: for even
/// `dof = 2n`, `ln term_i = −x/2 + i ln(x/2) − ln i!`; for odd, after `erfc(√(x/2))`,
/// `ln term_i = ½ ln(2x/π) − x/2 + i ln x − ln(3·5···(2i+1))`.
fn chi2_survival_logs(dof: usize, x: f64) -> f64 {
    let (ln_x, half) = (libm::log(x), 0.5 * x);
    if dof.is_multiple_of(2) {
        let ln_half = libm::log(half);
        let (mut lt, mut sum) = (-half, 0.0);
        for i in 0..dof / 2 {
            if i > 0 {
                lt += ln_half - libm::log(i as f64);
            }
            sum += libm::exp(lt);
        }
        sum.min(1.0)
    } else {
        let mut lt = 0.5 * libm::log(2.0 * x / core::f64::consts::PI) - half;
        let mut sum = 0.0;
        for i in 0..(dof - 1) / 2 {
            if i > 0 {
                lt += ln_x - libm::log((2 * i + 1) as f64);
            }
            sum += libm::exp(lt);
        }
        (libm::erfc(libm::sqrt(half)) + sum).min(1.0)
    }
}

/// The upper quantile `x` of χ² with `dof` degrees of freedom, `P(χ² > x) = p`, `p` in
/// (0, 1): bisection on [`chi2_survival`], which decreases in `x`. A `p` of 1 or more (or NaN)
/// gives 0, which no detector accepts as a threshold.
pub fn chi2_upper(dof: usize, p: f64) -> f64 {
    if p.is_nan() || p >= 1.0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    while chi2_survival(dof, hi) > p && hi < 1e9 {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi2_survival(dof, mid) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The probability, per test, that a nominal cycle raises an alarm: a rate of `per_hour`
/// false alarms per hour of flight, shared over the `3600 / period` tests an hour and the
/// `hypotheses` actuators tested in each (Bonferroni: an upper bound on the rate, however
/// the tests are correlated).
pub fn per_test(per_hour: f64, period: f64, hypotheses: usize) -> f64 {
    per_hour * period / 3600.0 / hypotheses.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_quantiles_meet_their_tables() {
        // the normal's: 1.959964 at 2.5 %, 3.090232 at 0.1 %, 6.361341 at 1e-10
        assert!((normal_upper(0.025) - 1.959_964).abs() < 1e-6);
        assert!((normal_upper(1e-3) - 3.090_232).abs() < 1e-6);
        assert!((normal_upper(1e-10) - 6.361_341).abs() < 1e-5);
        // χ² tables: 3.841459 (1, 5 %), 15.08627 (5, 1 %), 20.51501 (5, 0.1 %),
        // 9.210340 (2, 1 %), 16.26624 (3, 0.1 %), 10.82757 (1, 0.1 %)
        for (dof, p, x) in [
            (1, 0.05, 3.841_459),
            (5, 0.01, 15.086_27),
            (5, 1e-3, 20.515_01),
            (2, 0.01, 9.210_340),
            (3, 1e-3, 16.266_24),
            (1, 1e-3, 10.827_57),
        ] {
            assert!((chi2_upper(dof, p) - x).abs() < 1e-4, "{dof} {p}");
        }
        // χ²₂ in closed form, x = −2 ln p, far in the tail
        for p in [1e-6, 1e-9, 1e-12] {
            let exact = -2.0 * libm::log(p);
            assert!((chi2_upper(2, p) / exact - 1.0).abs() < 1e-9, "{p}");
        }
        // one degree agrees with the normal's square
        let z = normal_upper(0.5e-9);
        assert!((chi2_upper(1, 1e-9) / (z * z) - 1.0).abs() < 1e-9);
        assert!((per_test(3.6, 0.01, 8) - 1.25e-6).abs() < 1e-18);
    }

    #[test]
    fn many_degrees_of_freedom_are_summed_in_logarithms() {
        // at the seam the two sums agree
        for dof in [199, 200] {
            for x in [150.0, 200.0, 260.0, 320.0] {
                let (direct, logs) = (chi2_survival(dof, x), chi2_survival_logs(dof, x));
                assert!((direct - logs).abs() <= 1e-12 + 1e-9 * direct, "{dof} {x}");
            }
        }
        // the band of 2 000 degrees: its mean is at about half (the median is just below
        // the mean), and the normal approximation of its tail holds to a percent
        let k = 2000.0_f64;
        let at_mean = chi2_survival(2000, k);
        assert!((0.49..0.51).contains(&at_mean), "{at_mean}");
        let x = chi2_upper(2000, 1e-6);
        assert!(x.is_finite() && x > k, "{x}");
        // Wilson–Hilferty: k (1 − 2/(9k) + z √(2/(9k)))³
        let z = normal_upper(1e-6);
        let c = 2.0 / (9.0 * k);
        let wh = k * (1.0 - c + z * c.sqrt()).powi(3);
        assert!((x / wh - 1.0).abs() < 1e-3, "{x} {wh}");
        // odd degrees too, where the direct sum would overflow
        let odd = chi2_upper(1501, 1e-6);
        assert!(odd.is_finite() && odd > 1501.0 && odd < x, "{odd}");
        assert!((chi2_survival(1501, odd) / 1e-6 - 1.0).abs() < 1e-6);
    }
}
