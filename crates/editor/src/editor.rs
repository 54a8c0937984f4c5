//! The editor as a deterministic state machine: [`Editor::handle`] applies an event,
//! [`Editor::advance`] simulates one frame. No clock, no I/O.

use hooke_mesh::{Spring, SpringMesh};
use hooke_sim::scenes::Setup;
use hooke_sim::{
    Contact, Damping, ExternalForce, Integrator, Pins, Scene, Shape, SimError, Simulation, State,
};
use nalgebra::Vector2;

use crate::event::{Event, Key};
use crate::params::{EditorParams, IntegratorChoice, DASHPOT_FLOOR, DRAG_FLOOR, MAX_SUBSTEPS};
use crate::EditorError;

/// A 2D point or vector, m or m/s.
pub type Vec2 = Vector2<f64>;

/// A spring of the editor's model: the two particles and the rest length (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelSpring {
    /// First particle.
    pub i: u32,
    /// Second particle.
    pub j: u32,
    /// Rest length l, m (the stiffness is Y / l).
    pub rest_length: f64,
}

/// What [`Editor::handle`] asks of the front end.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Outcome {
    /// The event was applied (or had nothing to act on).
    Done,
    /// The user asked to save: write [`Editor::scene_file_text`] somewhere.
    SaveRequested,
}

/// What the last simulated frame's solver did, for the overlay.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Solver iterations summed over the frame's substeps (0 for explicit integrators).
    pub iterations: usize,
    /// The last substep's solver residual (the solver's own norm), if it solved a system.
    pub residual: Option<f64>,
    /// Substeps in which the linearised step fell back to the clamped Hessian.
    pub clamped_substeps: usize,
    /// Library steps taken, halved Newton steps counted as their pieces.
    pub pieces: usize,
}

/// The editor: the particle model (positions, velocities, pins, springs), the material and damping
/// settings, the chosen integrator, and the simulation built from them.
///
/// The model is the truth; the simulation is rebuilt from it whenever particles, springs, pins or
/// settings change (a projective dynamics factorisation per such change), and between changes it
/// is stepped in place, the model's state given to it with [`Simulation::set_motion`] before each
/// frame and read back after. A failure of any kind (the library refusing a step above the
/// explicit bound, a solver failing, NaN) is kept in [`Editor::failure`], the frame is undone and
/// the editor pauses; resuming (space) rebuilds and retries.
///
/// ```
/// use hooke_editor::{Editor, EditorParams, Event};
///
/// let mut editor = Editor::seed(EditorParams::default())?; // the default three particles
/// editor.handle(Event::Click { x: 0.35, y: 0.45, shift: false, pin: false })?;
/// assert_eq!(editor.particle_count(), 4);
/// for _ in 0..100 {
///     editor.advance();
/// }
/// assert!(editor.failure().is_none());
/// assert!(editor.positions().iter().all(|p| (0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y)));
/// # Ok::<(), hooke_editor::EditorError>(())
/// ```
#[derive(Debug)]
pub struct Editor {
    params: EditorParams,
    positions: Vec<Vec2>,
    velocities: Vec<Vec2>,
    pinned: Vec<bool>,
    springs: Vec<ModelSpring>,
    young: f64,
    drag: f64,
    dashpot: f64,
    substeps: usize,
    integrator: IntegratorChoice,
    paused: bool,
    frames: u64,
    cursor: Vec2,
    attracting: bool,
    dragging: Option<usize>,
    simulation: Option<Simulation<2>>,
    /// The model changed in a way the simulation must be rebuilt for.
    stale: bool,
    failure: Option<String>,
    notice: Option<String>,
    stats: FrameStats,
    /// Scratch copies of the state handed to the simulation (reused, so a frame allocates nothing).
    work_positions: Vec<Vec2>,
    work_velocities: Vec<Vec2>,
}

impl Editor {
    /// An empty editor (no particles).
    ///
    /// # Errors
    /// [`EditorError::InvalidParameter`] from [`EditorParams::validate`].
    pub fn new(params: EditorParams) -> Result<Self, EditorError> {
        params.validate()?;
        Ok(Editor {
            params,
            positions: Vec::new(),
            velocities: Vec::new(),
            pinned: Vec::new(),
            springs: Vec::new(),
            young: params.young,
            drag: params.drag,
            dashpot: params.dashpot,
            substeps: params.substeps,
            integrator: IntegratorChoice::SymplecticEuler,
            paused: false,
            frames: 0,
            cursor: Vec2::new(0.5, 0.5),
            attracting: false,
            dragging: None,
            simulation: None,
            stale: true,
            failure: None,
            notice: None,
            stats: FrameStats::default(),
            work_positions: Vec::new(),
            work_velocities: Vec::new(),
        })
    }

    /// The default start: particles at (0.3, 0.3), (0.3, 0.4), (0.4, 0.4), added as clicks.
    ///
    /// # Errors
    /// As [`Editor::new`].
    pub fn seed(params: EditorParams) -> Result<Self, EditorError> {
        let mut editor = Editor::new(params)?;
        for (x, y) in [(0.3, 0.3), (0.3, 0.4), (0.4, 0.4)] {
            editor.add_particle(Vec2::new(x, y), false);
        }
        Ok(editor)
    }

    /// Open a 2D scene (a scene file's or [`hooke_sim::scenes::seed_2d`]'s setup). The editor
    /// takes its particles, velocities, pins, springs, particle mass, gravity, drag, dashpot,
    /// integrator and time step over `params`'s (an explicit integrator's time step is the frame,
    /// split into the scene's substeps; an implicit one's is the editor's substep, as many to a
    /// frame as come closest to `params.frame_time`), and shows in [`Editor::notice`] what it runs
    /// differently (the file's solver settings, walls added to a scene without them).
    ///
    /// # Errors
    /// [`EditorError::UnsupportedScene`] for a scene the editor cannot model, naming what: more
    /// than `params.max_particles` particles, a particle outside the unit box, springs of different
    /// Young's moduli k·l, particles of different masses, gravity not pointing down, a force other
    /// than gravity, viscous damping, pins on a path, an obstacle other than the unit box's
    /// frictionless walls.
    pub fn from_setup(params: EditorParams, setup: &Setup<2>) -> Result<Self, EditorError> {
        let opened = crate::setup::open(params, setup)?;
        let mut editor = Editor::new(opened.params)?;
        editor.young = opened.young;
        editor.positions = setup.initial.positions.clone();
        editor.velocities = setup.initial.velocities.clone();
        editor.pinned = setup.scene.is_pinned().to_vec();
        editor.springs = setup
            .scene
            .mesh()
            .springs()
            .iter()
            .map(|s| ModelSpring {
                i: s.i,
                j: s.j,
                rest_length: s.rest_length,
            })
            .collect();
        editor.integrator = opened.integrator;
        editor.notice = opened.notice;
        Ok(editor)
    }

    /// Apply one event.
    ///
    /// # Errors
    /// [`EditorError::PositionOutsideBox`] for a position that is not finite or outside [0, 1]²
    /// (the event is then ignored).
    pub fn handle(&mut self, event: Event) -> Result<Outcome, EditorError> {
        if let Some((x, y)) = event.position() {
            if !((0.0..=1.0).contains(&x) && (0.0..=1.0).contains(&y)) {
                return Err(EditorError::PositionOutsideBox { x, y });
            }
            self.cursor = Vec2::new(x, y);
        }
        match event {
            Event::Click { x, y, shift, pin } => {
                let at = Vec2::new(x, y);
                if pin {
                    if let Some(v) = self.pick(at) {
                        self.pinned[v] = !self.pinned[v];
                        self.velocities[v] = Vec2::zeros();
                        self.stale = true;
                    }
                } else {
                    self.add_particle(at, shift);
                }
            }
            Event::Move { .. } => {}
            Event::RightPress { .. } => self.attracting = true,
            Event::RightRelease => self.attracting = false,
            Event::MiddlePress { .. } => {
                if let Some(v) = self.pick(self.cursor) {
                    self.dragging = Some(v);
                    self.stale = true;
                }
            }
            Event::MiddleRelease => {
                if let Some(v) = self.dragging.take() {
                    self.velocities[v] = Vec2::zeros();
                    self.stale = true;
                }
            }
            Event::Key { key, shift } => return Ok(self.key(key, shift)),
        }
        Ok(Outcome::Done)
    }

    fn key(&mut self, key: Key, shift: bool) -> Outcome {
        let factor = if shift { 1.0 / 1.1 } else { 1.1 };
        match key {
            Key::Space => {
                self.paused = !self.paused;
                if !self.paused && self.failure.take().is_some() {
                    self.stale = true;
                }
            }
            Key::C => self.clear(),
            Key::Y => {
                self.young *= factor;
                self.stale = true;
            }
            Key::D => {
                self.drag = stepped(self.drag, shift, DRAG_FLOOR);
                self.stale = true;
            }
            Key::X => {
                self.dashpot = stepped(self.dashpot, shift, DASHPOT_FLOOR);
                self.stale = true;
            }
            Key::I => {
                self.integrator = self.integrator.cycled(!shift);
                self.stale = true;
            }
            Key::BracketLeft => {
                self.substeps = (self.substeps / 2).max(1);
                self.stale = true;
            }
            Key::BracketRight => {
                self.substeps = (self.substeps * 2).min(MAX_SUBSTEPS);
                self.stale = true;
            }
            Key::S => return Outcome::SaveRequested,
        }
        Outcome::Done
    }

    /// Remove every particle and spring (the settings stay).
    pub fn clear(&mut self) {
        self.positions.clear();
        self.velocities.clear();
        self.pinned.clear();
        self.springs.clear();
        self.dragging = None;
        self.simulation = None;
        self.failure = None;
        self.notice = None;
        self.stats = FrameStats::default();
        self.stale = true;
    }

    /// Switch to `integrator` (as the integrator key does).
    pub fn set_integrator(&mut self, integrator: IntegratorChoice) {
        self.integrator = integrator;
        self.stale = true;
    }

    /// The particle nearest to `at` within the pick radius.
    fn pick(&self, at: Vec2) -> Option<usize> {
        let mut best = None;
        let mut best_distance = self.params.pick_radius;
        for (v, p) in self.positions.iter().enumerate() {
            let d = (p - at).norm();
            if d <= best_distance {
                best_distance = d;
                best = Some(v);
            }
        }
        best
    }

    /// A new particle, joined to every particle closer than the connection radius, with
    /// the rest length of the parameters. O(particles) per click.
    fn add_particle(&mut self, at: Vec2, pinned: bool) {
        if self.positions.len() >= self.params.max_particles {
            self.notice = Some(format!(
                "{} particles: the editor holds no more",
                self.params.max_particles
            ));
            return;
        }
        let new = self.positions.len() as u32;
        for (k, p) in self.positions.iter().enumerate() {
            if (p - at).norm() < self.params.connection_radius {
                self.springs.push(ModelSpring {
                    i: k as u32,
                    j: new,
                    rest_length: self.params.rest_length,
                });
            }
        }
        self.positions.push(at);
        self.velocities.push(Vec2::zeros());
        self.pinned.push(pinned);
        self.stale = true;
    }

    /// Build the simulation from the model. `None` when there is nothing for the library to
    /// solve: no particle free, or no spring at all (then free particles fall ballistically, see
    /// [`Editor::advance`]).
    fn build(&self) -> Result<Option<Simulation<2>>, SimError> {
        let held = |v: usize| self.pinned[v] || self.dragging == Some(v);
        let free = (0..self.positions.len()).filter(|&v| !held(v)).count();
        if free == 0 || self.springs.is_empty() {
            return Ok(None);
        }
        let springs = self
            .springs
            .iter()
            .map(|s| Spring {
                i: s.i,
                j: s.j,
                stiffness: self.young / s.rest_length,
                rest_length: s.rest_length,
            })
            .collect();
        let mesh = SpringMesh::new(
            self.positions.clone(),
            vec![self.params.particle_mass; self.positions.len()],
            springs,
        )?;
        let pins: Vec<u32> = (0..self.positions.len())
            .filter(|&v| held(v))
            .map(|v| v as u32)
            .collect();
        let dashpot = if self.integrator.models_dashpot() {
            self.dashpot
        } else {
            0.0
        };
        let scene = Scene::new(mesh, self.substep())?
            .with_pins(Pins::Vertices(pins))?
            .with_forces(vec![ExternalForce::Gravity {
                acceleration: Vec2::new(0.0, -self.params.gravity),
            }])?
            .with_damping(Damping {
                drag: self.drag,
                viscous: 0.0,
                dashpot,
            })?
            .with_contacts(vec![Contact::new(Shape::Box {
                min: Vec2::zeros(),
                max: Vec2::new(1.0, 1.0),
            })])?;
        let state = State {
            positions: self.positions.clone(),
            velocities: self.velocities.clone(),
            time: 0.0,
        };
        Simulation::new(scene, state, self.integrator.settings()).map(Some)
    }

    /// The substep h = frame time / substeps, s.
    pub fn substep(&self) -> f64 {
        self.params.frame_time / self.substeps as f64
    }

    /// Simulate one frame (unless paused): the right-button pull (the impulse
    /// v ← v − T s (x − p) on every free particle, T the frame time), the dragged particle held at
    /// the cursor, then `substeps` steps of the chosen integrator with gravity, drag, dashpot and
    /// the unit box walls. With no spring at all, free particles fall ballistically by symplectic
    /// Euler (every integrator but forward Euler takes that step when no spring couples anything).
    ///
    /// A failure undoes the frame, is kept in [`Editor::failure`] and pauses the editor.
    pub fn advance(&mut self) {
        self.frames += 1;
        if self.paused {
            return;
        }
        if self.stale {
            self.stale = false;
            match self.build() {
                Ok(simulation) => self.simulation = simulation,
                Err(error) => return self.fail(error),
            }
        }
        let n = self.positions.len();
        self.work_positions.clear();
        self.work_positions.extend_from_slice(&self.positions);
        self.work_velocities.clear();
        self.work_velocities.extend_from_slice(&self.velocities);
        if self.attracting {
            let pull = self.params.frame_time * self.params.attractor_strength;
            let cursor = self.cursor;
            for v in 0..n {
                if !self.pinned[v] && self.dragging != Some(v) {
                    let x = self.work_positions[v];
                    self.work_velocities[v] -= (x - cursor) * pull;
                }
            }
        }
        if let Some(v) = self.dragging {
            self.work_positions[v] = self.cursor;
            self.work_velocities[v] = Vec2::zeros();
        }
        let mut stats = FrameStats::default();
        match &mut self.simulation {
            Some(simulation) => {
                let outcome = step_frame(
                    simulation,
                    self.substeps,
                    &self.work_positions,
                    &self.work_velocities,
                    &mut stats,
                );
                if let Err(error) = outcome {
                    return self.fail(error);
                }
                let state = simulation.state();
                self.positions.copy_from_slice(&state.positions);
                self.velocities.copy_from_slice(&state.velocities);
            }
            None => {
                self.ballistic_frame();
                self.positions.copy_from_slice(&self.work_positions);
                self.velocities.copy_from_slice(&self.work_velocities);
            }
        }
        self.stats = stats;
    }

    /// Free particles with no spring to any other: symplectic Euler substeps (drag, walls).
    fn ballistic_frame(&mut self) {
        let h = self.substep();
        let drag = (-h * self.drag).exp();
        let g = Vec2::new(0.0, -self.params.gravity);
        for v in 0..self.work_positions.len() {
            if self.pinned[v] || self.dragging == Some(v) {
                self.work_velocities[v] = Vec2::zeros();
                continue;
            }
            let (x, u) = (&mut self.work_positions[v], &mut self.work_velocities[v]);
            for _ in 0..self.substeps {
                let previous = *u;
                *u = (*u + g * h) * drag;
                *x += if self.integrator == IntegratorChoice::ExplicitEuler {
                    previous * h
                } else {
                    *u * h
                };
                for a in 0..2 {
                    if x[a] < 0.0 {
                        x[a] = 0.0;
                        u[a] = 0.0;
                    } else if x[a] > 1.0 {
                        x[a] = 1.0;
                        u[a] = 0.0;
                    }
                }
            }
        }
    }

    fn fail(&mut self, error: SimError) {
        self.failure = Some(format!("{}: {error}", self.integrator.name()));
        self.paused = true;
        self.simulation = None;
        self.stale = true;
    }

    /// Positions, m.
    pub fn positions(&self) -> &[Vec2] {
        &self.positions
    }

    /// Velocities, m/s.
    pub fn velocities(&self) -> &[Vec2] {
        &self.velocities
    }

    /// One flag per particle.
    pub fn pinned(&self) -> &[bool] {
        &self.pinned
    }

    /// The springs.
    pub fn springs(&self) -> &[ModelSpring] {
        &self.springs
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.positions.len()
    }

    /// Young's modulus Y, N (spring stiffness k = Y / l).
    pub fn young(&self) -> f64 {
        self.young
    }

    /// Drag rate, 1/s.
    pub fn drag(&self) -> f64 {
        self.drag
    }

    /// Dashpot coefficient, N·s/m.
    pub fn dashpot(&self) -> f64 {
        self.dashpot
    }

    /// Substeps per frame.
    pub fn substeps(&self) -> usize {
        self.substeps
    }

    /// The chosen integrator.
    pub fn integrator(&self) -> IntegratorChoice {
        self.integrator
    }

    /// True while paused (by space, or by a failure).
    pub fn is_paused(&self) -> bool {
        self.paused
    }

    /// The last failure, shown until the user resumes or clears.
    pub fn failure(&self) -> Option<&str> {
        self.failure.as_deref()
    }

    /// A notice for the overlay (e.g. the particle budget is reached).
    pub fn notice(&self) -> Option<&str> {
        self.notice.as_deref()
    }

    /// Show `notice` in the overlay (a front end reporting a save), until the next one or a clear.
    pub fn set_notice(&mut self, notice: String) {
        self.notice = Some(notice);
    }

    /// Calls of [`Editor::advance`] so far, paused ones included.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// The last frame's solver figures.
    pub fn stats(&self) -> FrameStats {
        self.stats
    }

    /// The parameters.
    pub fn params(&self) -> &EditorParams {
        &self.params
    }

    /// The cursor, m, and whether the pull is on.
    pub fn cursor(&self) -> (Vec2, bool) {
        (self.cursor, self.attracting)
    }

    /// The particle being dragged.
    pub fn dragging(&self) -> Option<usize> {
        self.dragging
    }

    /// Strain |r|/l − 1 of spring `s` (0 at rest; a zero-length spring has strain −1).
    pub fn strain(&self, s: &ModelSpring) -> f64 {
        let r = self.positions[s.i as usize] - self.positions[s.j as usize];
        r.norm() / s.rest_length - 1.0
    }

    /// Total energy, J: kinetic, springs (½ k (|r| − l)²) and gravity (m g y, zero at the floor).
    pub fn energy(&self) -> f64 {
        let m = self.params.particle_mass;
        let kinetic: f64 = self
            .velocities
            .iter()
            .map(|v| 0.5 * m * v.norm_squared())
            .sum();
        let gravity: f64 = self
            .positions
            .iter()
            .map(|p| m * self.params.gravity * p.y)
            .sum();
        let springs: f64 = self
            .springs
            .iter()
            .map(|s| {
                let r = self.positions[s.i as usize] - self.positions[s.j as usize];
                let k = self.young / s.rest_length;
                0.5 * k * (r.norm() - s.rest_length).powi(2)
            })
            .sum();
        kinetic + gravity + springs
    }

    /// The library integrator behind the current choice.
    pub fn library_integrator(&self) -> Integrator {
        self.integrator.settings().integrator
    }
}

/// A damping setting after one press of its key: ×1.1 (`down`: ÷1.1) above `floor`. A
/// multiplication alone could never leave 0, so raising a value below `floor` sets `floor`, and
/// lowering one that would fall below `floor` sets 0: from 0, one press up and one down return to
/// exactly 0.
fn stepped(value: f64, down: bool, floor: f64) -> f64 {
    if down {
        let lowered = value / 1.1;
        if lowered < floor {
            0.0
        } else {
            lowered
        }
    } else {
        (value * 1.1).max(floor)
    }
}

/// `substeps` library steps from the given state; the solver figures into `stats`.
fn step_frame(
    simulation: &mut Simulation<2>,
    substeps: usize,
    positions: &[Vec2],
    velocities: &[Vec2],
    stats: &mut FrameStats,
) -> Result<(), SimError> {
    simulation.set_motion(positions, velocities)?;
    for _ in 0..substeps {
        let report = simulation.step()?;
        stats.pieces += report.substeps;
        if let Some(solver) = report.solver {
            stats.iterations += solver.iterations;
            stats.residual = Some(solver.residual);
        }
        if report.clamped_hessian {
            stats.clamped_substeps += 1;
        }
    }
    Ok(())
}
