//! The paper's run (a) on trajectory 1, in one process: the controller of
//! `companion-core` driving this crate's plant at 1 kHz for 20 s.
//!
//! ```text
//! cargo run -p companion-plant --example closed_loop --release [-- path/to/target.toml]
//! ```
//!
//! With a target file (see `examples/target.toml`) the target follows that file instead.

use companion_core::{Controller, PaperRun, Params, PlatformKind, Rpr, Unicycle};
use companion_plant::{paper_initial, PaperTrajectory, Plant, PlantConfig, Trajectory};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (trajectory, initial) = match std::env::args().nth(1) {
        Some(path) => {
            let t = Trajectory::load(&path)?;
            let initial = t.initial_conditions()?;
            (t, initial)
        }
        None => (Trajectory::Paper1, paper_initial(PaperTrajectory::One)),
    };
    let mut plant = Plant::new(PlantConfig::new(PlatformKind::Unicycle), Rpr::paper(), initial, trajectory)?;
    let mut controller =
        Controller::new(Params::<f64, 3>::paper(PaperRun::A), Unicycle::paper(), Rpr::paper())?;
    let dt = 1e-3;
    for n in 0..=20_000u64 {
        let measurement = plant.measure();
        let output = controller.step(&measurement, dt).map_err(|r| r.to_string())?;
        if n % 2000 == 0 {
            let s = plant.truth();
            println!(
                "t = {:5.1} s   |e_p| = {:.2e}   base = ({:+.3}, {:+.3}, {:+.3})   q = ({:+.3}, {:.3}, {:+.3})",
                s.t,
                output.diagnostics.e_p.norm(),
                s.base.x,
                s.base.y,
                s.base.theta,
                s.joints[0],
                s.joints[1],
                s.joints[2],
            );
        }
        plant.advance(&output.command, dt);
    }
    Ok(())
}
