//! Error budget of the twin: before/after, cross-validation, error against load.
use robocal_data::{ErrorStats, MeasurementSet};
use robocal_ident::{KinematicSettings, Observations, SolverKind, calibrate_kinematics};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let robot = robocal_robot::Robot::load("configs/robots/pmc6va030.toml")?;
    let data = MeasurementSet::read("datasets/pmc6va030/measurements.csv", 6)?;
    let unloaded = Observations::from_rows(6, data.rows.iter().filter(|r| r.sample.load == 0.0));
    for solver in [SolverKind::Lm, SolverKind::Bfgs] {
        let t = std::time::Instant::now();
        let cal = calibrate_kinematics(
            &robot,
            &unloaded,
            &KinematicSettings {
                solver,
                ..Default::default()
            },
        )?;
        let r = &cal.report;
        println!(
            "{:?}: {} iters ({}), {:?}; before mean {:.3} max {:.3}; after mean {:.3} std {:.3} max {:.3}; cond {:.1}; fixed {:?}",
            solver,
            r.iterations,
            r.termination,
            t.elapsed(),
            r.before.mean,
            r.before.max,
            r.after.mean,
            r.after.std,
            r.after.max,
            r.condition_number,
            r.fixed.iter().map(|f| f.name.clone()).collect::<Vec<_>>()
        );
        let mut by_load = String::new();
        for load in data.loads() {
            let obs =
                Observations::from_rows(6, data.rows.iter().filter(|r| r.sample.load == load));
            let s = ErrorStats::from_errors(&obs.errors(&cal.robot));
            by_load += &format!(" {load}:{:.3}", s.mean);
        }
        println!("  by load:{by_load}");
    }
    Ok(())
}
