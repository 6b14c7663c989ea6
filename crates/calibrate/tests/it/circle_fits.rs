//! Circle fits against closed-form cases, against each other on noisy arcs, the LM Jacobian against finite
//! differences, robust rejection, covariance against Monte-Carlo scatter, and the harmonic fit.

use calibrate::circle::{self, CircleError, Point};
use proptest::prelude::*;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::TAU;

fn ring(c: Point, r: f64, n: usize, phase: f64, arc: f64) -> Vec<Point> {
    (0..n)
        .map(|k| {
            let t = phase + arc * k as f64 / n as f64;
            [c[0] + r * t.cos(), c[1] + r * t.sin()]
        })
        .collect()
}

fn noisy(points: &[Point], sigma: f64, seed: u64) -> Vec<Point> {
    let mut rng = StdRng::seed_from_u64(seed);
    let n = Normal::new(0.0, sigma).expect("sigma");
    points
        .iter()
        .map(|p| [p[0] + n.sample(&mut rng), p[1] + n.sample(&mut rng)])
        .collect()
}

proptest! {
    #[test]
    fn every_fit_recovers_an_exact_circle(cx in -50.0..50.0f64, cy in -50.0..50.0f64, r in 1.0..300.0f64,
                                          n in 3usize..40, phase in 0.0..TAU, arc in 1.0..TAU) {
        let pts = ring([cx, cy], r, n, phase, arc);
        let tol = 1e-6 * (r + cx.abs() + cy.abs());
        for c in [circle::kasa(&pts).expect("kasa"), circle::taubin(&pts).expect("taubin"), circle::geometric(&pts).expect("lm").circle] {
            prop_assert!((c.cx - cx).abs() < tol && (c.cy - cy).abs() < tol && (c.r - r).abs() < tol, "{:?}", c);
        }
    }
}

#[test]
fn fits_agree_on_a_full_noisy_ring_and_kasa_is_biased_on_a_short_arc() {
    let full = noisy(&ring([3.0, -1.0], 100.0, 16, 0.2, TAU), 0.05, 1);
    let k = circle::kasa(&full).expect("kasa");
    let t = circle::taubin(&full).expect("taubin");
    let g = circle::geometric(&full).expect("geometric").circle;
    for c in [k, t] {
        assert!(
            (c.cx - g.cx).abs() < 0.01 && (c.cy - g.cy).abs() < 0.01 && (c.r - g.r).abs() < 0.01
        );
    }
    // On a 60° arc with noise, Kåsa's radius is known to shrink; the geometric fit stays unbiased on average.
    let (mut kasa_bias, mut geo_bias) = (0.0, 0.0);
    for seed in 0..200 {
        let arc = noisy(&ring([0.0, 0.0], 50.0, 20, 0.0, TAU / 6.0), 0.5, seed);
        kasa_bias += circle::kasa(&arc).expect("kasa").r - 50.0;
        geo_bias += circle::geometric(&arc).expect("geometric").circle.r - 50.0;
    }
    assert!(
        kasa_bias / 200.0 < -0.5,
        "kasa mean radius bias {}",
        kasa_bias / 200.0
    );
    assert!((geo_bias / 200.0).abs() < (kasa_bias / 200.0).abs() / 3.0);
}

#[test]
fn lm_jacobian_matches_finite_differences() {
    let pts = noisy(&ring([1.0, 2.0], 40.0, 9, 0.3, TAU), 0.2, 4);
    let (cx, cy, r) = (1.3, 1.7, 39.0);
    let res = |cx: f64, cy: f64, r: f64| -> Vec<f64> {
        pts.iter()
            .map(|p| (p[0] - cx).hypot(p[1] - cy) - r)
            .collect()
    };
    let h = 1e-6;
    let base = [cx, cy, r];
    for col in 0..3 {
        let mut up = base;
        let mut dn = base;
        up[col] += h;
        dn[col] -= h;
        let (a, b) = (res(up[0], up[1], up[2]), res(dn[0], dn[1], dn[2]));
        for (i, p) in pts.iter().enumerate() {
            let d = (p[0] - cx).hypot(p[1] - cy);
            let analytic = match col {
                0 => -(p[0] - cx) / d,
                1 => -(p[1] - cy) / d,
                _ => -1.0,
            };
            assert!(((a[i] - b[i]) / (2.0 * h) - analytic).abs() < 1e-7);
        }
    }
    // The fit's covariance uses that Jacobian: the reported σ must match the Monte-Carlo scatter.
    let truth = ring([0.0, 0.0], 100.0, 16, 0.0, TAU);
    let sigma = 0.05;
    let mut cxs = Vec::new();
    let mut reported = 0.0;
    for seed in 0..400 {
        let f = circle::geometric(&noisy(&truth, sigma, 100 + seed)).expect("fit");
        cxs.push(f.circle.cx);
        reported += f.covariance[0][0].sqrt();
    }
    let mean = cxs.iter().sum::<f64>() / cxs.len() as f64;
    let scatter =
        (cxs.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / (cxs.len() - 1) as f64).sqrt();
    let reported = reported / 400.0;
    // Closed form for N equally spaced points: σ_cx = σ·√(2/N).
    let closed = sigma * (2.0f64 / 16.0).sqrt();
    assert!(
        (scatter / closed - 1.0).abs() < 0.12,
        "scatter {scatter} vs {closed}"
    );
    assert!(
        (reported / closed - 1.0).abs() < 0.1,
        "reported {reported} vs {closed}"
    );
}

#[test]
fn robust_fit_rejects_a_spurious_point() {
    let mut pts = noisy(&ring([0.5, -0.5], 100.0, 16, 0.0, TAU), 0.01, 2);
    let plain_clean = circle::geometric(&pts).expect("fit").circle;
    pts[4] = [pts[4][0] * 0.9, pts[4][1] * 0.9]; // a spurious detection 10 mm inside
    let plain = circle::geometric(&pts).expect("fit").circle;
    let robust = circle::robust(&pts, 0.1).expect("robust");
    assert_eq!(robust.outliers, vec![4]);
    assert!((plain.cx - plain_clean.cx).hypot(plain.cy - plain_clean.cy) > 0.3);
    assert!((robust.circle.cx - plain_clean.cx).hypot(robust.circle.cy - plain_clean.cy) < 0.01);
    assert!(robust.residuals[4] < -9.0);
}

#[test]
fn centroid_is_the_centre_for_equal_spacing_only() {
    let pts = ring([2.0, -3.0], 80.0, 16, 0.4, TAU);
    let c = circle::centroid(&pts).expect("centroid");
    assert!((c[0] - 2.0).abs() < 1e-9 && (c[1] + 3.0).abs() < 1e-9);
    let half = ring([2.0, -3.0], 80.0, 8, 0.4, TAU / 2.0);
    let c = circle::centroid(&half).expect("centroid");
    assert!((c[0] - 2.0).hypot(c[1] + 3.0) > 10.0);
    assert!(matches!(
        circle::centroid(&half[..2]),
        Err(CircleError::TooFewPoints { .. })
    ));
}

#[test]
fn harmonic_fit_reads_the_ring_eccentricity() {
    // A ring of radius 100 centred at e = (0.3, −0.2): its radius seen from the origin at angle θ is
    // ≈ 100 + e·(cosθ, sinθ) to first order.
    let e = [0.3, -0.2];
    let thetas: Vec<f64> = (0..16).map(|k| k as f64 * TAU / 16.0).collect();
    let radii: Vec<f64> = thetas
        .iter()
        .map(|t| {
            let (c, s) = (t.cos(), t.sin());
            let proj = e[0] * c + e[1] * s;
            proj + (100.0f64.powi(2) - (e[0] * e[0] + e[1] * e[1] - proj * proj)).sqrt()
        })
        .collect();
    let h = circle::fit_harmonic(&thetas, &radii).expect("fit");
    assert!((h.b - 0.3).abs() < 1e-3 && (h.c + 0.2).abs() < 1e-3 && (h.a - 100.0).abs() < 1e-3);
}
