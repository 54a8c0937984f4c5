//! Snapshots: everything a running [`Simulation`] carries from one step to the next, so that a run
//! can be saved and continued with the same results, bit for bit.

use nalgebra::SVector;
use serde::{Deserialize, Serialize};

use super::Simulation;
use crate::{SimError, State};

/// The part of a [`Simulation`] that changes as it runs, taken after a step by
/// [`Simulation::snapshot`] and put back by [`Simulation::restore`].
///
/// A simulation is its scene, its settings and its initial state (all given to
/// [`Simulation::new`]) plus this: the current state, the number of frames taken, and the memory
/// of its integrator. A simulation built by [`Simulation::new`] from the same scene, initial state
/// and settings and then given a snapshot steps exactly as the simulation the snapshot was taken
/// from would have: the same positions and velocities, bit for bit, and the same step reports
/// (wall times aside). The solvers keep nothing else from step to step: Newton starts every step
/// from the inertial target with the exact Hessian (no warm start, no shift carried over),
/// projective dynamics from the inertial target with its constant factorisation, the linearised
/// integrator from the current velocities.
///
/// The reference values that [`Simulation::new`] derives from the initial state (the energy
/// watchdog's E₀ and limit, the divergence limit, the start time) are recorded too, so that
/// [`Simulation::restore`] can refuse a snapshot of another run. Serialisation (serde) keeps every
/// `f64` exactly with any format that round-trips floats (`serde_json`'s default does).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Snapshot<const D: usize> {
    /// Positions after the last step taken, one per vertex (m).
    pub positions: Vec<SVector<f64, D>>,
    /// Velocities after the last step taken, one per vertex (m/s).
    pub velocities: Vec<SVector<f64, D>>,
    /// Simulated time after the last step taken (s).
    pub time: f64,
    /// Frames stepped since the start ([`Simulation::steps_taken`]).
    pub steps_taken: usize,
    /// The initial state's time (s), from which frame times are counted.
    pub start_time: f64,
    /// The divergence limit (m) derived from the initial state's extent.
    pub divergence_limit: f64,
    /// The energy watchdog's reference E₀ and limit (J), if the watchdog applies.
    pub energy_limit: Option<[f64; 2]>,
    /// Backward Euler by Newton's halving back-off, one entry per halving depth that exists
    /// (depth 0 first: the frame's step size); empty for the other integrators.
    pub halving: Vec<HalvingMemory>,
}

/// What backward Euler by Newton remembers about failed steps at one step size (see the adaptive
/// halving in the `implicit` module): after a failure it halves the next few calls at that size
/// straight away.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct HalvingMemory {
    /// Calls at this step size still to go straight to halves.
    pub skip_whole: u32,
    /// Failures of the whole step in a row, which set the next back-off (1, 2, 4, … 16 calls).
    pub failure_streak: u32,
}

impl HalvingMemory {
    /// A memory with these counts.
    pub fn new(skip_whole: u32, failure_streak: u32) -> Self {
        HalvingMemory {
            skip_whole,
            failure_streak,
        }
    }
}

impl<const D: usize> Snapshot<D> {
    /// The state the snapshot holds.
    pub fn state(&self) -> State<D> {
        State {
            positions: self.positions.clone(),
            velocities: self.velocities.clone(),
            time: self.time,
        }
    }
}

impl<const D: usize> Simulation<D> {
    /// Everything this simulation carries into its next step (see [`Snapshot`]).
    pub fn snapshot(&self) -> Snapshot<D> {
        Snapshot {
            positions: self.state.positions.clone(),
            velocities: self.state.velocities.clone(),
            time: self.state.time,
            steps_taken: self.steps_taken,
            start_time: self.start_time,
            divergence_limit: self.divergence_limit,
            energy_limit: self.energy_limit.map(|(initial, limit)| [initial, limit]),
            halving: self
                .implicit
                .as_ref()
                .map_or_else(Vec::new, |i| i.halving_memory()),
        }
    }

    /// Continue from `snapshot`, taken from a simulation of the same scene, initial state and
    /// settings as this one: the following steps are then those that simulation would have taken.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming the snapshot's field, with this simulation left as it
    /// was, if the snapshot cannot be this simulation's: its vertex counts differ from the mesh's,
    /// a position or velocity is not finite, its start time, divergence limit or energy watchdog
    /// differ from those this simulation derived from its initial state and settings (bit for
    /// bit), or it has halving memory for an integrator that does not halve.
    pub fn restore(&mut self, snapshot: &Snapshot<D>) -> Result<(), SimError> {
        let n = self.scene.mesh().vertex_count();
        for (field, len) in [
            ("snapshot.positions", snapshot.positions.len()),
            ("snapshot.velocities", snapshot.velocities.len()),
        ] {
            if len != n {
                return Err(SimError::invalid(
                    field,
                    format!("{len} entries"),
                    format!("the mesh has {n} vertices"),
                ));
            }
        }
        let state = snapshot.state();
        super::check_finite(&state, snapshot.steps_taken)?;
        if !snapshot.time.is_finite() {
            return Err(SimError::invalid(
                "snapshot.time",
                snapshot.time,
                "must be finite",
            ));
        }
        let other_run =
            "differs from this simulation's: the snapshot is of another scene, initial \
                         state or settings";
        if snapshot.start_time.to_bits() != self.start_time.to_bits() {
            return Err(SimError::invalid(
                "snapshot.start_time",
                snapshot.start_time,
                other_run,
            ));
        }
        if snapshot.divergence_limit.to_bits() != self.divergence_limit.to_bits() {
            return Err(SimError::invalid(
                "snapshot.divergence_limit",
                snapshot.divergence_limit,
                other_run,
            ));
        }
        let bits = |limit: Option<[f64; 2]>| limit.map(|l| l.map(f64::to_bits));
        let ours = self.energy_limit.map(|(initial, limit)| [initial, limit]);
        if bits(snapshot.energy_limit) != bits(ours) {
            return Err(SimError::invalid(
                "snapshot.energy_limit",
                format!("{:?}", snapshot.energy_limit),
                other_run,
            ));
        }
        match &mut self.implicit {
            Some(implicit) => implicit.restore_halving_memory(
                &self.scene,
                &snapshot.halving,
                &snapshot.positions,
            )?,
            None if snapshot.halving.is_empty() => {}
            None => {
                return Err(SimError::invalid(
                    "snapshot.halving",
                    format!("{} entries", snapshot.halving.len()),
                    "this simulation's integrator does not halve steps",
                ))
            }
        }
        self.state = state;
        self.steps_taken = snapshot.steps_taken;
        Ok(())
    }
}
