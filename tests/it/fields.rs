//! Fields of problems several tests solve (no feature needed).

/// Kepler's field in the plane, y = (x, y, vₓ, v_y): g = (vₓ, v_y, −x/r³, −y/r³) (no linear
/// part).
pub fn kepler_field(y: &[f64], o: &mut [f64]) {
    let r2 = y[0] * y[0] + y[1] * y[1];
    let r3 = r2 * r2.sqrt();
    o[0] = y[2];
    o[1] = y[3];
    o[2] = -y[0] / r3;
    o[3] = -y[1] / r3;
}
