//! The paper's published figures (Hsiao et al., IEEE Access 2020), measured on its real
//! PMC6VA030 robot: printed beside ours for comparison, never as our results. Mean, standard
//! deviation and maximum of the Euclidean error, mm.

use robocal_ident::SolverKind;
use robocal_residual::ResidualKind;

/// Section V-A: the 168 unloaded configurations before calibration (nominal table).
pub const V_A_BEFORE: [f64; 3] = [3.704, 1.351, 7.909];
/// Section V-A: after BFGS kinematic calibration, same rows.
pub const V_A_AFTER: [f64; 3] = [0.383, 0.161, 0.556];
/// Section V-A2: mean error of the 56 held-out configurations in cross-validation.
pub const V_A_HELD_OUT_MEAN: f64 = 0.403;
/// Fig. 13: mean error after kinematic calibration at the heaviest load (20 kg).
pub const FIG13_HEAVIEST_MEAN: f64 = 0.94;

/// Table 5 (after BFGS + SOMM-ANN): training (GA10).
pub const TABLE5_TRAINING: [f64; 3] = [0.376, 0.204, 0.954];
/// Table 5: validation (GB20).
pub const TABLE5_VALIDATION: [f64; 3] = [0.397, 0.223, 1.010];
/// Table 5: test (GA20 + GB10 + GB30).
pub const TABLE5_TEST: [f64; 3] = [0.381, 0.213, 0.991];

/// Table 6 (the 840 GB10 + GB30 rows): before calibration.
pub const TABLE6_BEFORE: [f64; 3] = [2.613, 1.015, 6.294];
/// Table 6: after BFGS kinematic calibration.
pub const TABLE6_BFGS: [f64; 3] = [0.618, 0.275, 1.609];
/// Table 6: after BFGS + SOMM-ANN. The paper prints 0.991 as the standard deviation too, which
/// cannot be right (it equals the maximum); kept as printed.
pub const TABLE6_BFGS_SOMM: [f64; 3] = [0.389, 0.991, 0.991];
/// Table 6: after BFGS + CA-SOMM-ANN.
pub const TABLE6_BFGS_CA_SOMM: [f64; 3] = [0.310, 0.213, 1.255];
/// Section V-B3: the CA-SOMM classifier's accuracy.
pub const CLASSIFIER_ACCURACY: f64 = 0.93;

/// The Table 6 row of a model built from these stages: its label in the paper and its figures.
pub fn table6_row(
    solver: SolverKind,
    residual: Option<ResidualKind>,
) -> Option<(&'static str, [f64; 3])> {
    match (solver, residual) {
        (SolverKind::Bfgs, None) => Some(("After BFGS kinematic", TABLE6_BFGS)),
        (SolverKind::Bfgs, Some(ResidualKind::Somm)) => {
            Some(("After BFGS+SOMM-ANN", TABLE6_BFGS_SOMM))
        }
        (SolverKind::Bfgs, Some(ResidualKind::CaSomm)) => {
            Some(("After BFGS+CA-SOMM-ANN", TABLE6_BFGS_CA_SOMM))
        }
        _ => None,
    }
}
