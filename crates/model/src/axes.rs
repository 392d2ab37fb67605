//! The servo axes of a ring as the drivers move them: each holds its command between
//! events and is advanced exactly to the next event's true time. Independent axes are
//! [`ServoAxes`]; the coupled two-link arm is [`ArmAxes`]; [`Spec::plant`](crate::Spec::plant)
//! makes the one a scenario asks for.

use ringsync_plant::{AxisModel, Encoder};

mod arm;
pub use arm::ArmAxes;

use crate::scenario::{Scenario, ScenarioError};
use crate::spec::{encoders, scenario_err};

/// One servo axis with its encoder and the command it holds until the next one.
#[derive(Debug, Clone)]
pub struct ServoAxis {
    /// The drive and mechanics.
    pub model: AxisModel,
    /// The encoder.
    pub encoder: Encoder,
    /// Position \[rad\].
    pub x: f64,
    /// Velocity [rad/s].
    pub v: f64,
    /// True time of the state \[ns\].
    pub t: i64,
    /// Command held \[V\].
    pub u: f64,
}

impl ServoAxis {
    /// The scenario's axes at rest at position 0, true time 0, 0 V.
    pub fn for_scenario(s: &Scenario) -> Result<Vec<ServoAxis>, ScenarioError> {
        let models = s
            .axis_models()
            .map_err(|(i, e)| scenario_err(&format!("axis[{i}]"), e))?;
        Ok(models
            .into_iter()
            .zip(encoders(s)?)
            .map(|(model, encoder)| ServoAxis {
                model,
                encoder,
                x: 0.0,
                v: 0.0,
                t: 0,
                u: 0.0,
            })
            .collect())
    }

    /// Advances the state to true time `t` \[ns\] with the command held (no-op if `t` is not
    /// later than the state).
    pub fn advance(&mut self, t: i64) {
        if t > self.t {
            self.model
                .step(&mut self.x, &mut self.v, self.u, (t - self.t) as f64 * 1e-9);
            self.t = t;
        }
    }

    /// The encoder count of the current position.
    pub fn counts(&self) -> i64 {
        self.encoder.counts(self.x)
    }
}

/// The axes of a ring as the drivers move them: each axis holds the command its drive applies
/// and is advanced, with that command, to the true time of the next event that concerns it.
/// Independent axes ([`ServoAxes`]) advance one at a time; a coupled plant advances all its
/// axes together whenever one is asked for.
pub trait Axes: Send {
    /// Number of axes.
    fn len(&self) -> usize;
    /// Whether there is no axis.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Advances axis `i` (and whatever is coupled to it) to true time `t` \[ns\] with the
    /// commands held (no-op if `t` is not later).
    fn advance(&mut self, i: usize, t: i64);
    /// Position of axis `i` \[rad\] at [`Axes::time`].
    fn position(&self, i: usize) -> f64;
    /// Velocity of axis `i` [rad/s] at [`Axes::time`].
    fn velocity(&self, i: usize) -> f64;
    /// The true time axis `i`'s state is at \[ns\].
    fn time(&self, i: usize) -> i64;
    /// The encoder count of axis `i` now.
    fn counts(&self, i: usize) -> i64;
    /// The command axis `i`'s drive holds \[V\].
    fn command(&self, i: usize) -> f64;
    /// Sets the command axis `i`'s drive holds from now on \[V\].
    fn set_command(&mut self, i: usize, u: f64);
}

/// Mechanically independent servo axes (the paper's experiment).
#[derive(Debug, Clone)]
pub struct ServoAxes(pub Vec<ServoAxis>);

impl ServoAxes {
    /// The scenario's axes at rest at position 0, true time 0, 0 V.
    pub fn for_scenario(s: &Scenario) -> Result<Self, ScenarioError> {
        ServoAxis::for_scenario(s).map(ServoAxes)
    }
}

impl Axes for ServoAxes {
    fn len(&self) -> usize {
        self.0.len()
    }
    fn advance(&mut self, i: usize, t: i64) {
        self.0[i].advance(t);
    }
    fn position(&self, i: usize) -> f64 {
        self.0[i].x
    }
    fn velocity(&self, i: usize) -> f64 {
        self.0[i].v
    }
    fn time(&self, i: usize) -> i64 {
        self.0[i].t
    }
    fn counts(&self, i: usize) -> i64 {
        self.0[i].counts()
    }
    fn command(&self, i: usize) -> f64 {
        self.0[i].u
    }
    fn set_command(&mut self, i: usize, u: f64) {
        self.0[i].u = u;
    }
}
