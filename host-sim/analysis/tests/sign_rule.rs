//! The identification evaluates sign(q̇) by the joint's rule (the core's, in f64): a model it
//! fits without a sign band predicts no Coulomb torque at rest, as the joint computes it (the
//! identification's own sign gave +c at q̇ = 0, sign(0) = +1).

use joint_analysis::identify;

#[test]
fn the_identification_sign_is_the_joints() {
    assert_eq!(identify::sign_band(0.0, 0.0), 0.0, "sign(0) without a band");
    assert_eq!(identify::sign_band(-0.0, 0.0), 0.0);
    assert_eq!(identify::sign_band(-1.0e-12, 0.0), -1.0);
    assert_eq!(identify::sign_band(0.004, 0.01), 0.4);
    for i in -200..=200 {
        let v = f64::from(i) * 1.0e-4;
        for band in [0.0, 0.005, 0.01] {
            let joint = f64::from(joint_core::math::sign_smooth(v as f32, band as f32));
            assert!((identify::sign_band(v, band) - joint).abs() < 1.0e-6, "v {v}, band {band}");
        }
    }
}
