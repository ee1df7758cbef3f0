//! The joint-error part of a fit: which joints get compliances, where the coefficients start,
//! and the solve that holds back what the poses cannot separate.

use super::priors::harmonic_prior;
use super::report::{ComplianceReport, ErrorTermReport, Fixed, FixedParameter, JointCompliance};
use super::settings::{
    BACKLASH_BOUND_DEG, COMPLIANCE_BOUND, ComplianceSettings, HARMONIC_BOUND_DEG,
    KinematicSettings, PAYLOAD_COM_BOUND, SolverKind, TILT_START_SHARE, TORQUE_SHARE,
};
use crate::bfgs::run_bfgs;
use crate::error::{IdentError, Result};
use crate::identifiability::{Column, null_ridged_standard_deviations, standard_deviations};
use crate::lm::run_lm_until;
use crate::problem::{CalibrationProblem, LeastSquares, Observations};
use nalgebra::Vector3;
use robocal_robot::{Compliance, DEG_PER_KNM, ErrorParam, Flank, Harmonic, JointErrors, Robot};

/// The joints that carry the payload's gravity torque at the loaded points of `obs`: those whose
/// RMS torque is at least [`TORQUE_SHARE`] of the largest joint's (a vertical first axis, or a
/// flange roll with the payload on its axis, carries none). Returns the joints and each joint's
/// RMS torque per kg (N·m/kg).
pub fn default_compliance_joints(
    robot: &Robot,
    obs: &Observations,
    gravity: &Vector3<f64>,
    payload_com: &Vector3<f64>,
) -> (Vec<usize>, Vec<f64>) {
    let unit = Compliance::new(vec![0.0; robot.dof()], *gravity, *payload_com);
    let mut sums = vec![0.0; robot.dof()];
    let mut loaded = 0usize;
    for i in (0..obs.len()).filter(|&i| obs.loads[i] > 0.0) {
        loaded += 1;
        for (s, t) in sums.iter_mut().zip(unit.torques(robot, obs.joints(i), 1.0)) {
            *s += t * t;
        }
    }
    let rms: Vec<f64> = sums
        .iter()
        .map(|s| (s / loaded.max(1) as f64).sqrt())
        .collect();
    let largest = rms.iter().copied().fold(0.0, f64::max);
    let joints = (0..robot.dof())
        .filter(|&j| largest > 0.0 && rms[j] >= TORQUE_SHARE * largest)
        .collect();
    (joints, rms)
}

/// The compliance part of a problem: the start model, the joints to identify and what the
/// report says of how they were chosen.
pub(super) struct ComplianceChoice {
    pub(super) start: Compliance,
    pub(super) joints: Vec<usize>,
    pub(super) torque_per_kg: Vec<f64>,
    pub(super) joints_source: String,
    pub(super) payload_com_source: String,
}

pub(super) fn choose_compliance(
    settings: &ComplianceSettings,
    robot: &Robot,
    obs: &Observations,
) -> Result<ComplianceChoice> {
    let loads = obs.distinct_loads();
    if loads.len() < 2 {
        return Err(IdentError::Compliance(format!(
            "needs points at two or more loads to separate joint deflection from geometry; these data hold {}",
            match loads.first() {
                Some(l) => format!("only {l} kg"),
                None => "none".into(),
            }
        )));
    }
    let (payload_com, payload_com_source) = match settings.payload_com {
        Some(c) => (c, "settings".to_string()),
        None => (
            robot.tool,
            "the measured point (tool), as no payload_com was given".to_string(),
        ),
    };
    let (default, torque_per_kg) =
        default_compliance_joints(robot, obs, &settings.gravity, &payload_com);
    let (joints, joints_source) = match &settings.joints {
        Some(j) => {
            if let Some(&bad) = j.iter().find(|&&j| j >= robot.dof()) {
                return Err(IdentError::Compliance(format!(
                    "joint {} does not exist: the robot has {} joints",
                    bad + 1,
                    robot.dof()
                )));
            }
            (j.clone(), "settings".to_string())
        }
        None => (
            default,
            format!(
                "default: the joints whose RMS payload torque is at least {:.0} % of the largest joint's",
                100.0 * TORQUE_SHARE
            ),
        ),
    };
    if joints.is_empty() {
        return Err(IdentError::Compliance(
            "no joint carries the payload's gravity torque in these data (check gravity)".into(),
        ));
    }
    Ok(ComplianceChoice {
        start: Compliance::new(vec![0.0; robot.dof()], settings.gravity, payload_com),
        joints,
        torque_per_kg,
        joints_source,
        payload_com_source,
    })
}

/// The joint-error model identification starts from — the compliance choice's, with the
/// harmonics, self-weight and backlash terms `settings` ask for at zero, each harmonic reaching as far as
/// its joint's readings in `obs` allow ([`Harmonic::reach_of`]) — and its unknowns.
pub(super) fn joint_error_start(
    settings: &KinematicSettings,
    aligned: &Robot,
    choice: Option<&ComplianceChoice>,
    obs: &Observations,
) -> Result<(Option<JointErrors>, Vec<ErrorParam>)> {
    let mut start: Option<JointErrors> = choice.map(|c| c.start.clone());
    let mut params: Vec<ErrorParam> = choice.map_or_else(Vec::new, |c| {
        c.joints
            .iter()
            .map(|&j| ErrorParam::Compliance(j))
            .collect()
    });
    if let Some(je) = &settings.joint_errors {
        let dof = aligned.dof();
        let mut model = start
            .take()
            .unwrap_or_else(|| JointErrors::new(vec![0.0; dof], je.gravity, aligned.tool));
        let first_harmonic = model.harmonics.len();
        let joints: Vec<usize> = je
            .harmonic_joints
            .clone()
            .unwrap_or_else(|| (0..dof).collect());
        if let Some(&bad) = joints.iter().find(|&&j| j >= dof) {
            return Err(IdentError::Compliance(format!(
                "harmonics: joint {} does not exist: the robot has {dof} joints",
                bad + 1
            )));
        }
        model = model.with_harmonics(&joints, je.harmonics);
        let ranges = obs.joint_ranges();
        for i in first_harmonic..model.harmonics.len() {
            let joint = model.harmonics[i].joint;
            model.harmonics[i].reach = (ranges.as_ref())
                .map(|r| r[joint])
                .map(|[lo, hi]| Harmonic::reach_of(lo, hi));
            params.push(ErrorParam::HarmonicSin(i));
            params.push(ErrorParam::HarmonicCos(i));
        }
        if je.self_weight {
            let first = model.self_weight.len();
            model = model.with_self_weight(&(0..dof).collect::<Vec<_>>(), dof);
            params.extend((first..model.self_weight.len()).map(ErrorParam::SelfWeight));
        }
        if je.link_weights {
            let first = model.link_weights.len();
            model = model.with_link_weights(&(0..dof).collect::<Vec<_>>());
            params.extend((first..model.link_weights.len()).map(ErrorParam::LinkWeight));
        }
        if je.backlash {
            let first = model.backlash.len();
            model = model.with_backlash(&(0..dof).collect::<Vec<_>>());
            if let Some(home) = &je.backlash_home {
                if home.len() != dof {
                    return Err(IdentError::Compliance(format!(
                        "backlash_home: {} readings for a robot with {dof} joints",
                        home.len()
                    )));
                }
                for b in &mut model.backlash[first..] {
                    b.flank = Flank::Approach {
                        home: home[b.joint],
                    };
                }
            }
            if let Some(flanks) = &je.flanks {
                for b in &mut model.backlash[first..] {
                    if let Some(f) = flanks.get(b.joint) {
                        b.flank = f.clone();
                    }
                }
            }
            params.extend((first..model.backlash.len()).map(ErrorParam::Backlash));
        }
        if je.tilt {
            let first = model.tilts.len();
            model = model.with_tilts(&(0..dof).collect::<Vec<_>>());
            params.extend((first..model.tilts.len()).map(ErrorParam::Tilt));
        }
        if je.runout > 0 {
            let first = model.runouts.len();
            model = model.with_runouts(&(0..dof).collect::<Vec<_>>(), je.runout);
            for i in first..model.runouts.len() {
                let joint = model.runouts[i].wave.joint;
                model.runouts[i].wave.reach = (ranges.as_ref())
                    .map(|r| r[joint])
                    .map(|[lo, hi]| Harmonic::reach_of(lo, hi));
                params.push(ErrorParam::RunoutSin(i));
                params.push(ErrorParam::RunoutCos(i));
            }
        }
        start = Some(model);
    }
    // The compliances a first fit found, and the payload's centre of mass, which moves nothing
    // at zero compliance.
    if let (Some(model), Some(c)) = (start.as_mut(), &settings.compliance) {
        if let Some(values) = &c.start {
            for &p in &params {
                if let ErrorParam::Compliance(j) = p {
                    model.values[j] = values[j];
                }
            }
        }
        if c.identify_payload_com {
            params.extend((0..3).map(ErrorParam::PayloadCom));
        }
        // The tilts start at a small share of the compliances, each joint without one at their
        // mean: at zero tilt the links' weights would tilt nothing, and the identifiability
        // analysis, made at the start, would hold a weight the geometry absorbs for the torsion
        // alone at zero.
        let positive: Vec<f64> = model.values.iter().copied().filter(|v| *v > 0.0).collect();
        if !positive.is_empty() && c.start.is_some() {
            let mean = positive.iter().sum::<f64>() / positive.len() as f64;
            for t in &mut model.tilts {
                let own = model.values[t.joint];
                t.value = TILT_START_SHARE * if own > 0.0 { own } else { mean };
            }
        }
    }
    Ok((start, params))
}

/// Solves `problem` from zero (the start the problem was built at); a transmission harmonic
/// identified beyond what a gear can have is not one (the term fits an effect it does not model,
/// or the poses barely determine it, and it would not extrapolate): it is held at zero (moved
/// from `kept` to `fixed`) and the rest solved again, from zero too — not from where the first
/// solve left them: with backlash flanks the cost has several minima, and the harmonic held at
/// zero pulls the rest toward one that extrapolates worse (started there, on the development
/// twins the held-out scores are the same, but two rows lower and four higher against the truth,
/// the joint-1 extrapolation 0.0286 → 0.0543 mm on the paper's arm and 0.0112 → 0.0144 on ARM7).
/// Returns the solution, the iterations (every solve's) and why the last solve
/// stopped.
pub(super) fn solve_gated(
    problem: &mut CalibrationProblem<'_>,
    kept: &mut Vec<Column>,
    fixed: &mut Vec<FixedParameter>,
    settings: &KinematicSettings,
) -> Result<(Vec<f64>, u64, String)> {
    let mut iterations = 0;
    Ok(loop {
        let mut solved = solve_once(problem, kept, settings)?;
        iterations += solved.1;
        solved.1 = iterations;
        let Some(model) = problem.compliance_at(&solved.0) else {
            break solved;
        };
        // Whether a joint's compliance is judged plausible, as the settings ask.
        let gate = settings
            .compliance
            .as_ref()
            .is_some_and(|c| c.plausible_only);
        // The harmonics' prior, on an LM fit that has none yet.
        let prior_wanted = !problem.has_prior()
            && settings.solver == SolverKind::Lm
            && (settings.joint_errors.as_ref()).is_some_and(|je| je.harmonic_prior);
        // The fit's residuals and standard deviations, once, for the gate and the prior. Where
        // the data's covariance is singular (at the fit, a backlash whose rows all rest on one
        // flank is its joint's offset), the prior's spread comes from the deviations under a
        // vanishing ridge ([`null_ridged_standard_deviations`]): a fit without a prior would
        // be compared by the flank rounds with fits under one.
        let has_backlash = kept.iter().any(|c| matches!(c, Column::Backlash(_)));
        let fitted = (gate || prior_wanted || has_backlash).then(|| {
            let (r, jac) = problem.residuals_and_jacobian(&solved.0);
            let std = standard_deviations(&jac, &r);
            let for_prior = if prior_wanted && std.is_none() {
                null_ridged_standard_deviations(&jac, &r)
            } else {
                std.clone()
            };
            (r, std, for_prior)
        });
        let singular = fitted.as_ref().is_some_and(|(_, std, _)| std.is_none());
        let judge = Judge {
            problem,
            kept,
            model: &model,
            std: (fitted.as_ref())
                .filter(|_| gate)
                .and_then(|(_, std, _)| std.as_ref()),
            gate,
            one_flank: if singular && has_backlash {
                one_flank(problem, kept, &model, &solved.0)
            } else {
                Vec::new()
            },
        };
        let held: Vec<(usize, Held)> = (0..kept.len())
            .filter_map(|p| judge.held(p).map(|h| (p, h)))
            .collect();
        if held.is_empty() {
            // The harmonics' prior, once the gate holds none of them: its spread comes from the
            // plausible ones (a term beyond a gear's bound is no gear's), and every coefficient
            // is solved again under it from zero, like any other re-solve.
            if let Some((r, _, Some(std))) = fitted.as_ref().filter(|_| prior_wanted)
                && let Some((prior, spread)) = harmonic_prior(problem, &model, r, std)
            {
                problem.set_prior(prior, spread);
                continue;
            }
            break solved;
        }
        for (p, why) in &held {
            fixed.push(FixedParameter {
                name: kept[*p].to_string(),
                independent_fraction: 1.0,
                why: match why {
                    Held::Implausible(_) => Fixed::Implausible,
                    _ => Fixed::Bound,
                },
                reason: why.reason(problem, kept[*p]),
            });
        }
        let keep: Vec<usize> = (0..kept.len())
            .filter(|p| !held.iter().any(|(h, _)| h == p))
            .collect();
        *problem = problem.restricted(&keep);
        *kept = keep.iter().map(|&p| kept[p]).collect();
    })
}

/// One solve of `problem` from zero by the settings' solver: the solution, its iterations and
/// why it stopped.
fn solve_once(
    problem: &mut CalibrationProblem<'_>,
    kept: &[Column],
    settings: &KinematicSettings,
) -> Result<(Vec<f64>, u64, String)> {
    let u0 = vec![0.0; problem.unknowns()];
    if kept.is_empty() {
        return Ok((u0, 0, "nothing to identify".to_string()));
    }
    match settings.solver {
        SolverKind::Lm => run_lm_until(
            LeastSquares(problem),
            u0,
            settings.max_iterations,
            settings.deadline,
            settings.work.as_ref(),
        ),
        SolverKind::Bfgs => run_bfgs(problem, u0, settings.max_iterations),
    }
}

/// The backlash terms among `kept` whose rows all rest on one flank at the fit `u`, with that
/// flank (`±1`). Such a term is its joint's offset there (a torque flank's boundary turns with
/// the identified geometry, so the analysis at the start, which saw both flanks, cannot tell):
/// its split with the offset is left where the solver's path put it, and a pose on the other
/// flank, which the data never showed, would move by twice that.
fn one_flank(
    problem: &CalibrationProblem<'_>,
    kept: &[Column],
    model: &Compliance,
    u: &[f64],
) -> Vec<(usize, f64)> {
    let robot = problem.robot_at(u);
    let obs = problem.observations();
    kept.iter()
        .filter_map(|c| match c {
            Column::Backlash(j) => model.backlash.iter().find(|b| b.joint == *j),
            _ => None,
        })
        .filter_map(|b| {
            let mut sides =
                (0..obs.len()).map(|i| model.flank(b, &robot, obs.joints(i), obs.loads[i]));
            let first = sides.next()?;
            sides.all(|s| s == first).then_some((b.joint, first))
        })
        .collect()
}

/// Why a solve's unknown is held, and the value that made it so.
enum Held {
    /// A harmonic beyond a gear's bound, its amplitude (deg).
    Harmonic(f64),
    /// A backlash whose rows all rest on one flank (`±1`).
    OneFlank(f64),
    /// A backlash beyond a reducer's bound, its half play (deg).
    Backlash(f64),
    /// A coordinate of the payload's centre of mass beyond where a payload hangs (mm).
    PayloadCom(f64),
    /// A compliance or a tilting compliance no joint can have, in words.
    Implausible(String),
}

impl Held {
    /// The reason written into the report for the unknown of `column`.
    fn reason(&self, problem: &CalibrationProblem<'_>, column: Column) -> String {
        match (self, column) {
            (Held::Harmonic(amplitude), _) => format!(
                "held at zero: its harmonic came out at {amplitude:.3}° amplitude, beyond the {HARMONIC_BOUND_DEG}° a gear's transmission error can have (an effect it does not model, such as backlash, or poses that barely determine it)"
            ),
            (Held::OneFlank(side), _) => format!(
                "held at zero: at the fit every row rests on its {} flank, where it is its joint's offset (its flank's boundary turned with the identified geometry): the data cannot tell its play",
                if *side > 0.0 { "+" } else { "−" }
            ),
            (Held::Backlash(half_play), _) => format!(
                "held at zero: its backlash came out at {half_play:.3}° half play, beyond the {BACKLASH_BOUND_DEG}° a reducer's can have (an effect it does not model, or poses that barely move the point with the joint)"
            ),
            (Held::PayloadCom(c), _) => format!(
                "held at its start: it came out at {c:.0} mm, beyond the {PAYLOAD_COM_BOUND} mm from the flange a payload's centre of mass can lie (an effect it does not model, or loads that barely determine it)"
            ),
            (Held::Implausible(why), Column::Tilt(_)) => {
                format!("implausible: its tilting compliance {why}; held rigid")
            }
            (Held::Implausible(why), Column::Compliance(j)) => format!(
                "implausible: its compliance {why}; the stage was absorbing an effect it does not model (backlash whose side the torque sets, a wrong payload_com, link deflection), {}",
                held_compliance(problem, j)
            ),
            (Held::Implausible(why), _) => format!("implausible: {why}; held at its start"),
        }
    }
}

/// What judges a solve's unknowns: the problem, its unknowns' columns (`kept`), the joint-error
/// model at the solution, the unknowns' standard deviations where the compliances are gated
/// (`gate`), and the backlash terms whose rows rest on one flank.
struct Judge<'a, 'p> {
    problem: &'a CalibrationProblem<'p>,
    kept: &'a [Column],
    model: &'a Compliance,
    std: Option<&'a Vec<f64>>,
    gate: bool,
    one_flank: Vec<(usize, f64)>,
}

impl Judge<'_, '_> {
    /// Why unknown `p` is held, if it is: a harmonic or a backlash beyond its bound, a backlash
    /// on one flank, the payload's centre of mass beyond reach, an implausible compliance.
    fn held(&self, p: usize) -> Option<Held> {
        let model = self.model;
        match self.kept[p] {
            Column::Harmonic { joint, order, .. } => {
                let amplitude = (model.harmonics.iter())
                    .find(|h| h.joint == joint && h.order == order)
                    .map_or(0.0, |h| h.sin.hypot(h.cos).to_degrees());
                (amplitude > HARMONIC_BOUND_DEG).then_some(Held::Harmonic(amplitude))
            }
            Column::Backlash(j) => {
                let half_play = (model.backlash.iter())
                    .find(|b| b.joint == j)
                    .map_or(0.0, |b| b.value.abs().to_degrees());
                let side = self.one_flank.iter().find(|(k, _)| *k == j).map(|f| f.1);
                if half_play > BACKLASH_BOUND_DEG {
                    Some(Held::Backlash(half_play))
                } else {
                    side.map(Held::OneFlank)
                }
            }
            Column::PayloadCom(axis) => {
                let c = model.payload_com[axis];
                (!c.is_finite() || c.abs() > PAYLOAD_COM_BOUND).then_some(Held::PayloadCom(c))
            }
            _ => self.implausible(p).map(Held::Implausible),
        }
    }

    /// Why the compliance or tilting compliance of unknown `p` is impossible, when the settings
    /// ask (deg per kN·m).
    fn implausible(&self, p: usize) -> Option<String> {
        let model = self.model;
        let value = match self.kept[p] {
            Column::Compliance(j) => model.values[j],
            Column::Tilt(j) => (model.tilts.iter())
                .find(|t| t.joint == j)
                .map_or(0.0, |t| t.value),
            _ => return None,
        };
        if !self.gate {
            return None;
        }
        let value = value / DEG_PER_KNM;
        let std = self
            .std
            .map(|s| (s[p] * self.problem.scale()[p] / DEG_PER_KNM).abs());
        if value < 0.0 {
            Some(format!(
                "came out negative ({value:.4} deg/kN·m): no joint stiffens under load"
            ))
        } else if value > COMPLIANCE_BOUND {
            Some(format!(
                "came out at {value:.4} deg/kN·m, beyond the {COMPLIANCE_BOUND} deg/kN·m the default accepts"
            ))
        } else {
            std.filter(|s| *s >= value).map(|s| {
                format!(
                    "came out at {value:.4} ± {s:.4} deg/kN·m: no larger than its own uncertainty"
                )
            })
        }
    }
}

/// Where a compliance the gate holds stays, in words: rigid where the problem starts it at zero,
/// else at the value it starts from (the first fit's, without the links' weights, the payload's
/// centre of mass and backlash, which a restricted problem keeps).
pub(super) fn held_compliance(problem: &CalibrationProblem<'_>, joint: usize) -> String {
    let start =
        (problem.compliance_at(&vec![0.0; problem.unknowns()])).map_or(0.0, |m| m.values[joint]);
    if start == 0.0 {
        "held rigid".to_string()
    } else {
        format!(
            "held at {:.4} deg/kN·m, the value the first fit (without the links' weights, the payload's centre of mass and backlash) found",
            start / DEG_PER_KNM
        )
    }
}

/// The compliance part of the report: each joint's identified compliance (deg per kN·m), σ,
/// payload torque and why it was held (rigid, or at a first fit's value).
pub(super) fn compliance_report(
    choice: Option<&ComplianceChoice>,
    compliance: Option<&JointErrors>,
    obs: &Observations,
    kept: &[Column],
    fixed: &[FixedParameter],
    std_of: &dyn Fn(Column) -> Option<f64>,
) -> Option<ComplianceReport> {
    let identified = (0..3)
        .filter(|&axis| kept.contains(&Column::PayloadCom(axis)))
        .count();
    match (choice, compliance) {
        (Some(choice), Some(model)) => Some(ComplianceReport {
            gravity: model.gravity.into(),
            payload_com: model.payload_com.into(),
            payload_com_identified: identified,
            payload_com_source: match identified {
                0 => choice.payload_com_source.clone(),
                n => format!(
                    "identified with the compliances ({n} of 3 coordinates; started from {})",
                    choice.payload_com_source
                ),
            },
            joints_source: choice.joints_source.clone(),
            loads: obs.distinct_loads(),
            joints: (0..model.values.len())
                .map(|j| {
                    let column = Column::Compliance(j);
                    let identified = kept.contains(&column);
                    let reason = if identified && model.values[j] < 0.0 {
                        "identified, NEGATIVE: no joint stiffens under load; the stage is absorbing an effect it does not model (backlash whose side the torque sets, a wrong payload_com, link deflection); consider leaving this joint out".to_string()
                    } else if identified {
                        "identified".to_string()
                    } else if let Some(f) = fixed.iter().find(|f| f.name == column.to_string()) {
                        // Rigid, or at the first fit's value when the gate held it in the fit
                        // that started there (its reason says which).
                        if model.values[j] == 0.0 {
                            format!("held rigid: {}", f.reason)
                        } else {
                            format!("held: {}", f.reason)
                        }
                    } else {
                        "held rigid: not selected".to_string()
                    };
                    JointCompliance {
                        joint: j + 1,
                        compliance: model.values[j] / DEG_PER_KNM,
                        std: std_of(column).map(|s| s / DEG_PER_KNM),
                        torque_per_kg: choice.torque_per_kg[j],
                        identified,
                        reason,
                    }
                })
                .collect(),
        }),
        _ => None,
    }
}

/// The joint-error terms besides the compliances in the report (harmonics, self-weight, backlash,
/// the links' weights, the payload's centre of mass): value in its unit, σ, whether identified.
pub(super) fn joint_error_reports(
    model: &JointErrors,
    params: &[ErrorParam],
    kept: &[Column],
    std_of: &dyn Fn(Column) -> Option<f64>,
) -> Vec<ErrorTermReport> {
    params
        .iter()
        .filter(|p| !matches!(p, ErrorParam::Compliance(_)))
        .map(|&p| {
            let column = Column::of_error(model, p);
            ErrorTermReport {
                name: model.param_name(p),
                unit: match p {
                    ErrorParam::SelfWeight(_) => "deg per basis unit",
                    ErrorParam::LinkWeight(i) => model.link_weights[i].part.weight_unit(),
                    ErrorParam::PayloadCom(_) => "mm",
                    ErrorParam::Tilt(_) => "deg per kN·m",
                    _ => "deg",
                },
                value: in_file_unit(p, model.param(p)),
                std: std_of(column).map(|s| in_file_unit(p, s)),
                identified: kept.contains(&column),
            }
        })
        .collect()
}

/// A joint-error coefficient (internal units) in its report's: a link weight's kg or kg·m and
/// the payload's centre of mass's mm as they are, a tilting compliance in deg per kN·m, the rest
/// from radians to degrees.
pub(super) fn in_file_unit(p: ErrorParam, value: f64) -> f64 {
    match p {
        ErrorParam::LinkWeight(_) | ErrorParam::PayloadCom(_) => value,
        ErrorParam::Tilt(_) => value / DEG_PER_KNM,
        _ => value.to_degrees(),
    }
}
