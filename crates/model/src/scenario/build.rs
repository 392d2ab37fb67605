//! Making a run's objects from a scenario's values: the ring parameters of the planner, the
//! gains, the control law, the desired motion and the axes' plant models.

use ringsync_control::law::registry::{self, LawEntry, LawParams};
use ringsync_control::{
    AxisTrajectory, ControlError, ControlLaw, Cosine, Gains, Sequence, Sign, SyncParams, Trapezoid,
    VelocitySource,
};
use ringsync_plant::{AxisModel, Friction, PlantError, SignModel, TorqueAxis, VelocityAxis};
use ringsync_proto::RingParams;

use super::error::{ScenarioError, control_error, out_of_range};
use super::schema::{
    AxisKind, AxisSpec, CoulombSign, PerAxis, Scenario, TrajectorySpec, VelocityKind,
};

impl Scenario {
    /// Number of axes n (= slaves).
    pub fn axes_count(&self) -> usize {
        self.ring.slaves as usize
    }

    /// The cycle-plan parameters of the ring.
    pub fn ring_params(&self) -> RingParams {
        let r = &self.ring;
        RingParams {
            slaves: r.slaves,
            bit_rate_bps: r.bit_rate.0,
            phy_rx: r.phy_rx.0,
            phy_tx: r.phy_tx.0,
            cable_m: r.cable_m,
            propagation_ns_per_m: r.propagation_ns_per_m,
            residence: r.residence.0,
            response_delay: r.response_delay.0,
            t_rest: r.t_rest.0,
            t_cyc: r.cycle.0,
            ..RingParams::default()
        }
    }

    /// The gains of all n axes.
    pub fn gains(&self) -> Gains {
        let n = self.axes_count();
        let c = &self.control;
        Gains {
            kp: c.kp.expand(n),
            kd: c.kd.expand(n),
            ke: c.ke.expand(n),
            kh: c.kh.expand(n),
            kc: c.kc.expand(n),
            kf: c.kf.expand(n),
            kf_velocity: c.kf_velocity,
            // NaN without [[axis]] tables: Gains::validate rejects it.
            u_max: (0..n)
                .map(|i| self.axis_spec(i).map_or(f64::NAN, |a| a.u_max))
                .collect(),
        }
    }

    /// Whether any axis has a Coulomb feed-forward K_F.
    pub(crate) fn pd_kf_set(&self) -> bool {
        match &self.control.kf {
            PerAxis::One(v) => *v != 0.0,
            PerAxis::Each(v) => v.iter().any(|v| *v != 0.0),
        }
    }

    /// The disturbance observer's parameters (`control.dob_bandwidth` > 0): the nominal
    /// model is the feed-forward's, K_H and K_C per axis.
    pub fn dob_params(&self) -> Option<ringsync_control::dob::DobParams> {
        let c = &self.control;
        (c.dob_bandwidth != 0.0).then(|| {
            let g = self.gains();
            ringsync_control::dob::DobParams {
                bandwidth_hz: c.dob_bandwidth,
                h: g.kh,
                c: g.kc,
                u_max: g.u_max,
            }
        })
    }

    /// The `[[axis]]` table of axis `i` (0-based): the tables are used in turn; `None`
    /// when there is none.
    pub fn axis_spec(&self, i: usize) -> Option<&AxisSpec> {
        self.axis.get(i % self.axis.len().max(1))
    }

    /// Whether standard PD adds the feed-forward K_H·ẍ^d + K_C·ẋ^d + K_F·sat(ẋ^d/v_F): when
    /// any K_H, K_C or K_F is not zero.
    pub fn pd_feed_forward(&self) -> bool {
        let g = |p: &PerAxis| match p {
            PerAxis::One(v) => *v != 0.0,
            PerAxis::Each(v) => v.iter().any(|v| *v != 0.0),
        };
        g(&self.control.kh) || g(&self.control.kc) || g(&self.control.kf)
    }

    /// The controller's name in outputs: the built law's ([`ControlLaw::name`]), e.g. `pd+ff`
    /// for standard PD with feed-forward; the registry's name when the law cannot be built.
    pub fn law_name(&self) -> &'static str {
        match self.law() {
            Ok(law) => law.name(),
            Err(_) => self.law_entry().map_or("?", |e| e.name),
        }
    }

    /// The sync controller's parameters.
    pub fn sync_params(&self) -> SyncParams {
        let c = &self.control;
        SyncParams {
            alpha: c.alpha,
            delta_h: c.delta_h,
            delta_c: c.delta_c,
            sign: if c.boundary_layer == 0.0 {
                Sign::Exact
            } else {
                Sign::BoundaryLayer(c.boundary_layer)
            },
            estimator: c.estimator,
            extrapolate_own: c.extrapolate_own,
        }
    }

    /// The registry's entry of `control.law`; the error lists the known names.
    pub fn law_entry(&self) -> Result<&'static LawEntry, ScenarioError> {
        let name = &self.control.law;
        registry::find(name).ok_or_else(|| {
            out_of_range(
                "control.law",
                format!("\"{name}\""),
                format!(
                    "the name of a law: {}",
                    registry::names().collect::<Vec<_>>().join(", ")
                ),
            )
        })
    }

    /// What the law is built from: the common `[control]` values and the law's own
    /// parameters from `[control.params]`. Each key must be one the law declares, with one
    /// number for every axis or a list of n, in its range; the error names the key
    /// (`control.params.<key>`), the value and what is allowed.
    pub fn law_params(&self) -> Result<LawParams, ScenarioError> {
        let entry = self.law_entry()?;
        let n = self.axes_count();
        let mut p = LawParams::new(self.gains(), self.pd_feed_forward(), self.sync_params());
        for (key, value) in &self.control.params {
            let at = format!("control.params.{key}");
            let Some(spec) = entry.param(key) else {
                let others = registry::laws_with_param(key);
                return Err(ScenarioError::UnknownParameter {
                    key: key.clone(),
                    law: entry.name.to_string(),
                    known: entry.param_list(),
                    owners: if others.is_empty() {
                        String::new()
                    } else {
                        format!("; {key} is a parameter of {others}")
                    },
                });
            };
            let values = match value {
                PerAxis::One(v) => vec![*v; n],
                PerAxis::Each(v) if v.len() == n => v.clone(),
                PerAxis::Each(_) => {
                    return Err(out_of_range(
                        at,
                        value,
                        format!("one number for every axis, or a list of {n} (one per axis)"),
                    ));
                }
            };
            if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !spec.allows(**v)) {
                let at = match value {
                    PerAxis::One(_) => at,
                    PerAxis::Each(_) => format!("{at} (axis {})", i + 1),
                };
                return Err(out_of_range(at, v, spec.allowed()));
            }
            p.set(spec.key, values);
        }
        Ok(p)
    }

    /// The control law from the registry, checked.
    pub fn law(&self) -> Result<Box<dyn ControlLaw>, ScenarioError> {
        let entry = self.law_entry()?;
        entry
            .build(&self.law_params()?)
            .map_err(|e| control_error(&e))
    }

    /// Where ė comes from.
    pub fn velocity_source(&self) -> VelocitySource {
        match self.control.velocity {
            VelocityKind::Reported => VelocitySource::Reported,
            VelocityKind::Differenced => VelocitySource::Differenced,
            VelocityKind::Observer => VelocitySource::Observer(ringsync_control::ErrorObserver {
                bandwidth_hz: self.control.observer_bandwidth,
            }),
        }
    }

    /// The plant model of every axis; on error, the axis index and the error.
    pub fn axis_models(&self) -> Result<Vec<AxisModel>, (usize, PlantError)> {
        (0..self.axes_count())
            .map(|i| {
                let k = i % self.axis.len().max(1);
                let a = self.axis.get(k).ok_or((
                    k,
                    PlantError::InvalidParameter {
                        name: "axis",
                        value: 0.0,
                        expected: "at least one [[axis]] table",
                    },
                ))?;
                let model = match a.model {
                    AxisKind::Torque => {
                        let ka = a.rated_torque / a.u_max;
                        let friction = Friction {
                            viscous: a.viscous,
                            coulomb: a.coulomb_fraction * a.rated_torque,
                            sign: match a.coulomb_sign {
                                CoulombSign::Exact => SignModel::Exact,
                                CoulombSign::Smooth => SignModel::Smooth {
                                    v_s: a.coulomb_velocity_scale,
                                },
                            },
                        };
                        TorqueAxis::new(a.j_over_ka * ka, ka, friction, a.u_max)
                            .map(AxisModel::Torque)
                    }
                    AxisKind::Velocity => {
                        VelocityAxis::new(a.velocity_gain, a.time_constant.secs(), a.u_max)
                            .map(AxisModel::Velocity)
                    }
                };
                model.map_err(|e| (k, e))
            })
            .collect()
    }

    /// The desired motion of every axis: one for all, or for a part program each drive's
    /// share of the planned path.
    pub fn trajectories(&self) -> Result<Vec<AxisTrajectory>, ControlError> {
        let one = match &self.trajectory {
            TrajectorySpec::Program { .. } => return self.program_trajectories(),
            TrajectorySpec::Cosine { peak_speed, period } => {
                AxisTrajectory::Cosine(Cosine::with_peak_speed(*peak_speed, period.secs())?)
            }
            TrajectorySpec::Trapezoid {
                distance,
                v_max,
                a_max,
            } => AxisTrajectory::Trapezoid(Trapezoid::new(0.0, *distance, *v_max, *a_max, 0.0)?),
            TrajectorySpec::Sequence {
                targets,
                v_max,
                a_max,
            } => AxisTrajectory::Sequence(Sequence::new(0.0, targets, *v_max, *a_max, 0.0)?),
        };
        Ok(vec![one; self.axes_count()])
    }

    /// Each ring axis's share of the planned part program.
    fn program_trajectories(&self) -> Result<Vec<AxisTrajectory>, ControlError> {
        let refused = |e: ScenarioError| ControlError::InvalidParameter {
            name: "program".into(),
            value: f64::NAN,
            expected: e.to_string().into(),
        };
        let path = self.planned_path().map_err(refused)?;
        let map = self.machine_map().map_err(refused)?;
        let (Some(path), Some(map)) = (path, map) else {
            return Err(refused(out_of_range(
                "trajectory.kind",
                "\"program\"",
                "a [machine] table",
            )));
        };
        (0..self.axes_count())
            .map(|i| match map.drive(i) {
                Some((coord, rad_per_mm)) => Ok(AxisTrajectory::Path(ringsync_control::PathAxis {
                    path: path.clone(),
                    coord,
                    rad_per_mm,
                })),
                // A ring axis no machine axis lists holds still at 0.
                None => Ok(AxisTrajectory::Sequence(Sequence::new(
                    0.0,
                    &[],
                    1.0,
                    1.0,
                    0.0,
                )?)),
            })
            .collect()
    }
}
