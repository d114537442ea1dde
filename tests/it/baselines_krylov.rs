//! The matrix-free (Krylov) EEI3s4 against the dense one, and its order.

use crate::common_ec;

use common_ec::{fitted_order, max_abs_diff};
use ecr::baselines::exponential::Exprb43;
use ecr::baselines::krylov::Exprb43Krylov;
use ecr::problems::{Duffing, Nls};

#[test]
fn krylov_exprb43_equals_the_dense_one() {
    let p = Duffing::new(1.0, 0.5).unwrap();
    let mut a = Exprb43::new(p.system().unwrap(), 0.1).unwrap();
    let mut b = Exprb43Krylov::new(p.system().unwrap(), 0.1).unwrap();
    let (mut y, mut z) = (p.initial_value(), p.initial_value());
    for _ in 0..100 {
        a.step(&mut y).unwrap();
        b.step(&mut z).unwrap();
    }
    let d = max_abs_diff(&y, &z);
    println!("Duffing, 100 steps: dense vs Krylov exprb43 differ by {d:.2e}");
    // Both use finite differences for g' (different ones: a dense Jacobian vs directional
    // derivatives), each accurate to ~ε^(2/3) ≈ 4e-11.
    assert!(d <= 1e-9, "{d:e}");
    // NLS with N = 32 (d = 64): FFT skew pair for A.
    let nls = Nls::new(32).unwrap();
    let mut a = Exprb43::new(nls.system().unwrap(), 0.01).unwrap();
    let mut b = Exprb43Krylov::new(nls.system().unwrap(), 0.01).unwrap();
    let (mut y, mut z) = (nls.initial_value(), nls.initial_value());
    for _ in 0..20 {
        a.step(&mut y).unwrap();
        b.step(&mut z).unwrap();
    }
    let d = max_abs_diff(&y, &z);
    println!("NLS N = 32, 20 steps: dense vs Krylov exprb43 differ by {d:.2e}");
    assert!(d <= 1e-9, "{d:e}");
}

#[test]
fn krylov_exprb43_has_order_4() {
    let p = Duffing::new(1.0, 0.5).unwrap();
    let t_end = 2.0;
    let exact = p.exact(t_end).unwrap();
    let (mut hs, mut es) = (Vec::new(), Vec::new());
    for n in [20usize, 28, 40, 56, 80, 112, 160] {
        let mut st = Exprb43Krylov::new(p.system().unwrap(), t_end / n as f64).unwrap();
        let mut y = p.initial_value();
        for _ in 0..n {
            st.step(&mut y).unwrap();
        }
        hs.push(t_end / n as f64);
        es.push(max_abs_diff(&y, &exact));
    }
    let (o, k) = fitted_order(&hs, &es, 1e-11, 1.0);
    println!("Krylov exprb43: order {o:.3} ({k} points) {es:?}");
    assert!(k >= 4 && (o - 4.0).abs() <= 0.2, "{o}");
}
