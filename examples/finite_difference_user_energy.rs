//! Checking your own energy with hooke's finite-difference helpers (`hooke::assembly::fd`).
//!
//! The energy here is a user's own term, not one hooke has: a bending penalty on a chain of three
//! points, E(x) = ½ k_b (1 − cos θ)·2 = k_b (1 − u·w) with u, w the unit directions of the two
//! segments (θ the bend angle), written with its analytic gradient and Hessian. The helpers check
//! both against central differences with tolerances scaled by the size of what is compared.
//!
//! `cargo run --example finite_difference_user_energy`; `cargo test` runs it too.

use hooke::assembly::fd;
use nalgebra::{DMatrix, Matrix3, Vector3};

/// Bending stiffness k_b (J).
const BENDING: f64 = 0.7;

/// The three points of `x` (9 coordinates, m).
fn points(x: &[f64]) -> [Vector3<f64>; 3] {
    std::array::from_fn(|k| Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]))
}

/// E(x) = k_b (1 − u·w) (J).
fn energy(x: &[f64]) -> f64 {
    let [a, b, c] = points(x);
    let (u, w) = ((b - a).normalize(), (c - b).normalize());
    BENDING * (1.0 - u.dot(&w))
}

/// d(r/|r|)/dr = (I − r̂ r̂ᵀ)/|r|.
fn unit_jacobian(r: &Vector3<f64>) -> Matrix3<f64> {
    let n = r.norm();
    let rh = r / n;
    (Matrix3::identity() - rh * rh.transpose()) / n
}

/// ∇E (J/m), 9 entries.
fn gradient(x: &[f64]) -> Vec<f64> {
    let [a, b, c] = points(x);
    let (r, s) = (b - a, c - b);
    let (u, w) = (r.normalize(), s.normalize());
    // dE/dr = −k_b J(r) w, dE/ds = −k_b J(s) u; r = b − a, s = c − b.
    let de_dr = -BENDING * unit_jacobian(&r) * w;
    let de_ds = -BENDING * unit_jacobian(&s) * u;
    let ga = -de_dr;
    let gb = de_dr - de_ds;
    let gc = de_ds;
    ga.iter()
        .chain(gb.iter())
        .chain(gc.iter())
        .copied()
        .collect()
}

/// ∇²E by differentiating the analytic gradient once more, exactly: the blocks of d(J(r) w)/dr
/// need the second derivative of r/|r|, so here the Hessian is the Jacobian of `gradient`,
/// assembled from the chain rule on r and s.
fn hessian(x: &[f64]) -> DMatrix<f64> {
    let [a, b, c] = points(x);
    let (r, s) = (b - a, c - b);
    let (u, w) = (r.normalize(), s.normalize());
    // d/dr [J(r) w] = −(r̂ (J w)ᵀ + (r̂·w) J + J w r̂ᵀ)/|r| with J = J(r) (symmetric).
    let second = |r: &Vector3<f64>, w: &Vector3<f64>| {
        let (n, rh, j) = (r.norm(), r.normalize(), unit_jacobian(r));
        -(rh * (j * w).transpose() + rh.dot(w) * j + j * w * rh.transpose()) / n
    };
    let jr = unit_jacobian(&r);
    let js = unit_jacobian(&s);
    // dE/dr = −k_b J(r) w(s), dE/ds = −k_b J(s) u(r).
    let rr = -BENDING * second(&r, &w);
    let ss = -BENDING * second(&s, &u);
    let rs = -BENDING * jr * js; // d(dE/dr)/ds
                                 // Map (r, s) = (b − a, c − b) to (a, b, c): D = [[−I, I, 0], [0, −I, I]].
    let mut h = DMatrix::zeros(9, 9);
    let d = |k: usize| -> [f64; 2] {
        match k {
            0 => [-1.0, 0.0],
            1 => [1.0, -1.0],
            _ => [0.0, 1.0],
        }
    };
    for p in 0..3 {
        for q in 0..3 {
            let (dp, dq) = (d(p), d(q));
            let block = rr * (dp[0] * dq[0])
                + rs * (dp[0] * dq[1])
                + rs.transpose() * (dp[1] * dq[0])
                + ss * (dp[1] * dq[1]);
            h.view_mut((3 * p, 3 * q), (3, 3)).copy_from(&block);
        }
    }
    h
}

// README: begin
fn run() {
    // A bent chain: segments of 0.4 m and 0.3 m at about 50°.
    let x = [0.0, 0.0, 0.0, 0.4, 0.05, 0.0, 0.55, 0.3, 0.1];
    // The energy varies over the segment length: step 1e-5 of the shorter segment (see fd's docs).
    let step = fd::suggested_step(0.3);

    let numeric = fd::gradient(energy, &x, step);
    let analytic = gradient(&x);
    let scale = analytic.iter().map(|g| g.abs()).fold(0.0, f64::max);
    let error = numeric
        .iter()
        .zip(&analytic)
        .map(|(n, a)| (n - a).abs())
        .fold(0.0, f64::max);
    println!("gradient: largest entry {scale:.3e} J/m, largest error {error:.1e}");
    // Central differences at h = 1e-5 L are accurate to ~1e-9 of the entries' size; 1e-6 leaves a
    // margin and still fails for any wrong term (those are off by O(1) of the size).
    assert!(
        error <= 1e-6 * scale,
        "gradient error {error:.3e} over {scale:.3e}"
    );

    let numeric = fd::jacobian(|x, g| g.copy_from_slice(&gradient(x)), &x, 9, step);
    let analytic = hessian(&x);
    let scale = analytic.amax();
    let error = (&numeric - &analytic).amax();
    println!("Hessian: largest entry {scale:.3e} J/m², largest error {error:.1e}");
    assert!(
        error <= 1e-6 * scale,
        "Hessian error {error:.3e} over {scale:.3e}"
    );
    assert!((&analytic - analytic.transpose()).amax() <= 1e-12 * scale);
}
// README: end

fn main() {
    run();
}

#[test]
fn the_user_energy_matches_its_finite_differences() {
    run();
}
