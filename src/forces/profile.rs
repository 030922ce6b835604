//! Time profiles of the applied forces and torques.

/// Piecewise-linear interpolation of (t, value) pairs, constant outside.
pub fn piecewise_linear(profile: &[[f64; 2]], t: f64) -> f64 {
    match profile {
        [] => 0.0,
        [only] => only[1],
        _ => {
            if t <= profile[0][0] {
                return profile[0][1];
            }
            for w in profile.windows(2) {
                if t <= w[1][0] {
                    let s = (t - w[0][0]) / (w[1][0] - w[0][0]);
                    return w[0][1] + s * (w[1][1] - w[0][1]);
                }
            }
            profile[profile.len() - 1][1]
        }
    }
}
