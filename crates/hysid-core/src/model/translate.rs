//! A mechanical model written as a gray-box model: the same physics in the
//! general language, so that one simulator can run both
//! (`docs/mechanical-models.md`, "As a gray-box model").
//!
//! The states are the position `y` and velocity `v` (`y' = v`); the smooth
//! forces add up to the definition `F`; every set of engaged contacts is a
//! mode, whose flow subtracts the engaged contacts' forces and whose
//! definitions add their friction to both levels; a contact engages and
//! releases by guard transitions; the friction and the stops are the
//! gray-box elements of the same names. Mode labels are the mechanical
//! ones: a set of contacts takes its slip mode's name, the friction's stick
//! label is the stick mode's and a stop's rest label its stop mode's.

use hysid_graybox::compile::is_identifier;
use hysid_graybox::{
    Element, GrayBoxInitialState, GrayBoxMode, GrayBoxModel, GrayBoxTransition, InvalidGrayBox,
    OutputMap, StopSide,
};
use hysid_mechanical::{
    Direction, ForceElement, InvalidMechanical, MechanicalInitialState, MechanicalModel, Quantity,
};
use std::collections::{BTreeMap, HashSet};

/// Why a mechanical model has no gray-box form.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Untranslatable {
    /// The model is not a mechanical one (its kind).
    #[error("a '{0}' model; only a 'mechanical' model has a gray-box form")]
    NotMechanical(&'static str),
    /// The mechanical model itself is invalid.
    #[error(transparent)]
    Mechanical(#[from] InvalidMechanical),
    /// The written model does not check (e.g. a parameter whose name is
    /// not an expression's symbol).
    #[error("as a gray-box model: {0}")]
    GrayBox(#[from] InvalidGrayBox),
}

/// The gray-box form of `model`, checked: the same parameters, inputs,
/// internal step, initial state rule, regimes and mode labels.
pub fn to_gray_box(model: &MechanicalModel) -> Result<GrayBoxModel, Untranslatable> {
    let gray = written(model)?;
    gray.validate()?;
    Ok(gray)
}

/// The gray-box form of `model`, the mechanical model checked, the form
/// not: for a run, whose compilation checks it.
pub(crate) fn written(model: &MechanicalModel) -> Result<GrayBoxModel, InvalidMechanical> {
    model.validate()?;
    let symbols = Symbols::new(model);
    let labels = mode_labels(model);
    let gray = GrayBoxModel {
        format: hysid_graybox::FORMAT_VERSION,
        name: model.name.clone(),
        internal_step: model.internal_step,
        states: vec![symbols.y.clone(), symbols.v.clone()],
        inputs: symbols.inputs.clone(),
        delays: BTreeMap::new(),
        outputs: vec![OutputMap {
            name: symbols.y.clone(),
            value: symbols.y.clone(),
        }],
        parameters: model.parameters.clone(),
        definitions: model_definitions(model, &symbols),
        modes: contact_modes(model, &symbols, &labels),
        transitions: contact_transitions(model, &symbols, &labels.names),
        elements: elements(model, &symbols, &labels),
        energy: None,
        initial_state: initial_state(&model.initial_state, &symbols),
        info: model.info.clone(),
    };
    Ok(gray)
}

/// Per mode label of `gray`, the gray-box form of `model`
/// ([`GrayBoxModel::mode_names`]), the index of the mechanical mode of that
/// name: the form's labels are the mechanical modes' names.
pub fn mechanical_labels(model: &MechanicalModel, gray: &GrayBoxModel) -> Vec<usize> {
    gray.mode_names()
        .iter()
        .map(|label| {
            let declared = model.modes.iter().position(|q| q.name == *label);
            // `to_gray_box` labels every regime by a declared mode's name.
            declared.unwrap_or_default()
        })
        .collect()
}

/// The names the written model gives its states and definitions, each
/// kept apart from the parameters' and inputs' names.
struct Symbols {
    /// The inputs' names, in order.
    inputs: Vec<String>,
    y: String,
    v: String,
    force: String,
    kinetic: String,
    static_level: String,
    /// The friction element's name (apart from the stops' names).
    friction: String,
    /// Per contact: its penetration `p` and contact force `lambda`.
    contacts: Vec<(String, String)>,
}

impl Symbols {
    fn new(model: &MechanicalModel) -> Self {
        let mut taken: HashSet<String> = model
            .parameters
            .iter()
            .map(|p| p.name.clone())
            .chain(model.inputs.iter().cloned())
            .collect();
        let mut fresh = |base: &str| {
            let mut name = base.to_string();
            while !taken.insert(name.clone()) {
                name.push('_');
            }
            name
        };
        let mut friction = "friction".to_string();
        while model.stops.iter().any(|s| s.name == friction) {
            friction.push('_');
        }
        // Inputs are read by position: one whose name is no gray-box name
        // takes a fresh one.
        let inputs = (model.inputs.iter().enumerate())
            .map(|(i, name)| match is_identifier(name) {
                true => name.clone(),
                false => fresh(&format!("u{}", i + 1)),
            })
            .collect();
        Symbols {
            friction,
            inputs,
            y: fresh("y"),
            v: fresh("v"),
            force: fresh("F"),
            kinetic: fresh("kinetic"),
            static_level: fresh("static"),
            contacts: model
                .contacts
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    // Named after the contact where its name can follow
                    // `p_` in a symbol.
                    let symbol = c
                        .name
                        .chars()
                        .all(|h| h.is_ascii_alphanumeric() || h == '_');
                    let tag = if symbol {
                        c.name.clone()
                    } else {
                        (i + 1).to_string()
                    };
                    (fresh(&format!("p_{tag}")), fresh(&format!("lambda_{tag}")))
                })
                .collect(),
        }
    }
}

/// A quantity as an expression: a parameter's name or the number, exactly
/// (in parentheses when negative).
fn quantity(q: &Quantity) -> String {
    match q {
        Quantity::Param(name) => name.clone(),
        Quantity::Value(x) if x.is_sign_negative() => format!("({x:?})"),
        Quantity::Value(x) => format!("{x:?}"),
    }
}

/// A sum of terms, each added (`true`) or subtracted: `a - b + c` (`0`
/// for none).
pub fn signed_sum(terms: &[(bool, String)]) -> String {
    let mut out = String::new();
    for (i, (added, term)) in terms.iter().enumerate() {
        out.push_str(match (i, added) {
            (0, true) => "",
            (0, false) => "-",
            (_, true) => " + ",
            (_, false) => " - ",
        });
        out.push_str(term);
    }
    if out.is_empty() { "0".to_string() } else { out }
}

/// The labels of the regimes and the names of the gray-box modes: per set
/// of engaged contacts (by bit mask) its slip label, its mode's name and
/// its stick label; a rest label per stop.
struct Labels {
    slip: Vec<String>,
    names: Vec<String>,
    stick: Vec<String>,
    stops: Vec<String>,
}

impl Labels {
    /// The `label` of the mode of contacts `mask`, where it is not its
    /// name.
    fn label(&self, mask: usize) -> Option<String> {
        (self.names[mask] != self.slip[mask]).then(|| self.slip[mask].clone())
    }

    /// The friction's stick label in the mode of contacts `mask`, where it
    /// is not the friction's own (that of no contact engaged).
    fn stick_in(&self, mask: usize) -> Option<&String> {
        (self.stick[mask] != self.stick[0]).then_some(&self.stick[mask])
    }
}

/// Every regime's label is its first matching declared mode's name
/// (`MechanicalModel::mode_of`). A mode is named by its slip label where
/// that is an identifier no earlier set of contacts took; else
/// `contacts_<mask>` (made unique), labelled by the slip label.
fn mode_labels(model: &MechanicalModel) -> Labels {
    let name = |i: Option<usize>| {
        // `validate` proved that every regime has a mode.
        i.map(|i| model.modes[i].name.clone()).unwrap_or_default()
    };
    let masks = 0..(1u32 << model.contacts.len());
    let slip: Vec<String> = masks
        .clone()
        .map(|m| name(model.mode_of(None, false, m)))
        .collect();
    let stick = masks.map(|m| name(model.mode_of(None, true, m))).collect();
    let stops = (0..model.stops.len())
        .map(|i| name(model.mode_of(Some(i), false, 0)))
        .collect();
    let mut taken: HashSet<String> = model.modes.iter().map(|q| q.name.clone()).collect();
    let mut named = HashSet::new();
    let names = slip
        .iter()
        .enumerate()
        .map(|(mask, label)| {
            if is_identifier(label) && named.insert(label.clone()) {
                return label.clone();
            }
            let mut name = format!("contacts_{mask}");
            while !taken.insert(name.clone()) {
                name.push('_');
            }
            name
        })
        .collect();
    Labels {
        slip,
        names,
        stick,
        stops,
    }
}

/// `F`, the friction levels with no contact engaged, and each contact's
/// penetration `p = s (y - position)` and force `lambda = k p + d s v`.
fn model_definitions(model: &MechanicalModel, s: &Symbols) -> BTreeMap<String, String> {
    let terms: Vec<(bool, String)> = model
        .forces
        .iter()
        .map(|f| match f {
            ForceElement::Input { input, gain } => {
                // `validate` proved that every input force names an input.
                let i = model.inputs.iter().position(|n| n == input);
                let input = i.map_or(input, |i| &s.inputs[i]);
                (true, format!("{}*{input}", quantity(gain)))
            }
            ForceElement::Constant { value } => (true, quantity(value)),
            ForceElement::Spring { stiffness, rest } => {
                let stretch = match rest {
                    Quantity::Value(x) if *x == 0.0 => s.y.clone(),
                    rest => format!("({} - {})", s.y, quantity(rest)),
                };
                (false, format!("{}*{stretch}", quantity(stiffness)))
            }
            ForceElement::Damper { coefficient } => {
                (false, format!("{}*{}", quantity(coefficient), s.v))
            }
        })
        .collect();
    let mut out = BTreeMap::new();
    out.insert(s.force.clone(), signed_sum(&terms));
    out.insert(s.kinetic.clone(), quantity(&model.friction.kinetic));
    out.insert(
        s.static_level.clone(),
        quantity(&model.friction.static_level),
    );
    for (c, (p, lambda)) in model.contacts.iter().zip(&s.contacts) {
        let position = quantity(&c.position);
        let positive = c.direction == Direction::Positive;
        out.insert(
            p.clone(),
            if positive {
                format!("{} - {position}", s.y)
            } else {
                format!("{position} - {}", s.y)
            },
        );
        out.insert(
            lambda.clone(),
            signed_sum(&[
                (true, format!("{}*{p}", quantity(&c.stiffness))),
                (positive, format!("{}*{}", quantity(&c.damping), s.v)),
            ]),
        );
    }
    out
}

/// One mode per set of engaged contacts (bit `i` of the mask: contact `i`):
/// `y' = v`, `v' = F` less the engaged contacts' forces, their friction
/// added to both levels (definitions of the mode), and the invariant of
/// that set.
fn contact_modes(model: &MechanicalModel, s: &Symbols, labels: &Labels) -> Vec<GrayBoxMode> {
    (0..(1u32 << model.contacts.len()))
        .map(|mask| {
            let engaged = |i: usize| mask & (1 << i) != 0;
            let mut force = vec![(true, s.force.clone())];
            let mut definitions = BTreeMap::new();
            if mask != 0 {
                let mut kinetic = vec![(true, quantity(&model.friction.kinetic))];
                let mut static_level = vec![(true, quantity(&model.friction.static_level))];
                for (i, c) in model
                    .contacts
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| engaged(*i))
                {
                    // The contact pushes against its side: `-s lambda`.
                    let lambda = &s.contacts[i].1;
                    force.push((c.direction == Direction::Negative, lambda.clone()));
                    kinetic.push((true, quantity(&c.friction)));
                    static_level.push((true, quantity(&c.friction)));
                }
                definitions.insert(s.kinetic.clone(), signed_sum(&kinetic));
                definitions.insert(s.static_level.clone(), signed_sum(&static_level));
            }
            let invariant = model
                .contacts
                .iter()
                .zip(&s.contacts)
                .enumerate()
                .flat_map(|(i, (c, (p, lambda)))| match (engaged(i), c.unilateral) {
                    (true, true) => vec![format!("{p} >= 0"), format!("{lambda} >= 0")],
                    (true, false) => vec![format!("{p} >= 0")],
                    (false, true) => vec![format!("min({p}, {lambda}) <= 0")],
                    (false, false) => vec![format!("{p} <= 0")],
                })
                .collect();
            let mask = mask as usize;
            let doc = model
                .modes
                .iter()
                .find(|m| m.name == labels.slip[mask])
                .map(|m| m.doc.clone())
                .unwrap_or_default();
            GrayBoxMode {
                name: labels.names[mask].clone(),
                label: labels.label(mask),
                element_modes: labels
                    .stick_in(mask)
                    .map(|stick| (s.friction.clone(), stick.clone()))
                    .into_iter()
                    .collect(),
                flow: [
                    (s.y.clone(), s.v.clone()),
                    (s.v.clone(), signed_sum(&force)),
                ]
                .into(),
                invariant,
                definitions,
                doc,
            }
        })
        .collect()
}

/// Each contact engages (penetration past zero and, when unilateral, a
/// pushing force) and releases (a unilateral contact when its force would
/// pull, or the penetration back to zero) from every set of the others.
fn contact_transitions(
    model: &MechanicalModel,
    s: &Symbols,
    names: &[String],
) -> Vec<GrayBoxTransition> {
    let mut out = Vec::new();
    let mut add = |from: u32, to: u32, guard: String, when: Option<String>| {
        out.push(GrayBoxTransition {
            from: names[from as usize].clone(),
            to: names[to as usize].clone(),
            guard,
            when,
            reset: BTreeMap::new(),
            doc: String::new(),
        })
    };
    for mask in 0..(1u32 << model.contacts.len()) {
        for (i, (c, (p, lambda))) in model.contacts.iter().zip(&s.contacts).enumerate() {
            let bit = 1u32 << i;
            if mask & bit == 0 {
                if c.unilateral {
                    add(
                        mask,
                        mask | bit,
                        format!("{p} >= 0"),
                        Some(format!("{lambda} >= 0")),
                    );
                    add(
                        mask,
                        mask | bit,
                        format!("{lambda} >= 0"),
                        Some(format!("{p} >= 0")),
                    );
                } else {
                    add(mask, mask | bit, format!("{p} >= 0"), None);
                }
            } else {
                if c.unilateral {
                    add(mask, mask & !bit, format!("{lambda} <= 0"), None);
                }
                add(mask, mask & !bit, format!("{p} <= 0"), None);
            }
        }
    }
    out
}

/// The stops, then the friction (the gray-box simulator takes stops before
/// frictions in any order).
fn elements(model: &MechanicalModel, s: &Symbols, labels: &Labels) -> Vec<Element> {
    model
        .stops
        .iter()
        .zip(&labels.stops)
        .map(|(stop, label)| Element::Stop {
            name: stop.name.clone(),
            position: s.y.clone(),
            velocity: s.v.clone(),
            at: quantity(&stop.position),
            side: match stop.direction {
                Direction::Positive => StopSide::Max,
                Direction::Negative => StopSide::Min,
            },
            restitution: format!("{:?}", stop.restitution),
            rest_speed: 0.0,
            mode: label.clone(),
        })
        .chain(std::iter::once(Element::DryFriction {
            name: s.friction.clone(),
            velocity: s.v.clone(),
            kinetic: s.kinetic.clone(),
            static_level: s.static_level.clone(),
            mode: labels.stick[0].clone(),
        }))
        .collect()
}

fn initial_state(rule: &MechanicalInitialState, s: &Symbols) -> GrayBoxInitialState {
    match *rule {
        MechanicalInitialState::Measured {
            samples,
            velocity_tol,
        } => GrayBoxInitialState::Measured {
            // A mechanical warm-up of 0 samples reads the first one.
            samples: samples.max(1),
            position: s.y.clone(),
            velocity: Some(s.v.clone()),
            velocity_tol,
            values: BTreeMap::new(),
            mode: None,
            estimate: BTreeMap::new(),
        },
        MechanicalInitialState::Given { position, velocity } => GrayBoxInitialState::Given {
            values: [(s.y.clone(), position), (s.v.clone(), velocity)].into(),
            mode: None,
            estimate: BTreeMap::new(),
            samples: None,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_graybox::CompiledModel;
    use hysid_model::data::Dataset;
    use hysid_model::excitation::Excitation;
    use proptest::prelude::*;

    /// The repository's mounting head (`models/pick-and-place/head.toml`)
    /// with its free parameters at `z` (0: the lower bound, 1: the upper).
    fn head(z: &[f64]) -> MechanicalModel {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/pick-and-place/head.toml"
        );
        let Ok(crate::model::Model::Mechanical(mut m)) =
            crate::model::Model::load(std::path::Path::new(path))
        else {
            panic!("head.toml is a mechanical model")
        };
        for (p, zi) in m.parameters.iter_mut().zip(z) {
            if !p.fixed {
                p.value = p.bounds[0] + (p.bounds[1] - p.bounds[0]) * zi;
            }
        }
        m
    }

    /// An input of held random levels in `[low, high]`, and an output
    /// whose first samples set a measured initial state at `y0`.
    fn record(seed: u64, n: usize, low: f64, high: f64, y0: f64) -> Dataset {
        let ex = Excitation {
            n,
            hold: 40,
            low,
            high,
            ts: Some(0.0025),
            inputs: 1,
        };
        Dataset::siso(ex.generate(seed).remove(0), vec![y0; n], Some(0.0025)).unwrap()
    }

    /// The largest output difference of the two simulators on `data`, the
    /// first sample whose mode labels differ, and the gray-box run's events
    /// and Zeno steps.
    fn compare(m: &MechanicalModel, data: &Dataset) -> (f64, Option<usize>, usize, usize) {
        let g = to_gray_box(m).unwrap();
        let c = CompiledModel::new(&g).unwrap();
        let a = hysid_graybox::simulate::run(&c, &g.values(), data).unwrap();
        let b = hysid_mechanical::simulate::run(m, &m.values(), data).unwrap();
        let names = g.mode_names();
        let worst =
            a.y.iter()
                .zip(&b.y)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max);
        let label = (0..data.len()).find(|&k| {
            a.modes[k].map(|i| names[i].as_str()) != b.modes[k].map(|i| m.modes[i].name.as_str())
        });
        assert!(
            a.covered.iter().all(|c| *c),
            "a sample outside its mode's invariant"
        );
        (worst, label, a.events, a.zeno.map_or(0, |z| z.steps))
    }

    #[test]
    fn the_head_runs_alike() {
        let m = head(&[0.5; 12]);
        for seed in 0..5 {
            let data = record(seed, 1200, -0.3, 0.05, 3.0);
            let (worst, label, events, _) = compare(&m, &data);
            assert!(
                worst < 1e-9 && label.is_none() && events > 0,
                "seed {seed}: {worst} {label:?} {events}"
            );
        }
    }

    /// A contact: position, side, stiffness, damping, friction, unilateral.
    type ContactDraw = (f64, bool, f64, f64, f64, bool);

    /// A mechanical model of random structure: an input gain, a constant,
    /// a spring and a damper (given as parameters or numbers), friction,
    /// up to two contacts of either side and kind, a stop on either side
    /// (inelastic or bouncing), and a given or measured initial state.
    /// Its regimes are labelled by their contacts, or (`shared`) sliding
    /// and sticking without contact apart from one label each for every
    /// set of engaged contacts.
    fn drawn(
        forces: [f64; 5],
        friction: [f64; 2],
        contacts: &[ContactDraw],
        restitution: [f64; 2],
        given: Option<(f64, f64)>,
        shared: bool,
    ) -> MechanicalModel {
        let [gain, constant, stiffness, rest, damping] = forces;
        let param = |name: &str, value: f64| hysid_mechanical::PhysicalParameter {
            name: name.to_string(),
            unit: String::new(),
            value,
            bounds: [value - 1.0, value + 1.0],
            fixed: false,
            doc: String::new(),
        };
        let q = Quantity::Value;
        let names: Vec<String> = (0..contacts.len()).map(|i| format!("c{i}")).collect();
        use hysid_mechanical::{MechanicalMode, MechanicalModeKind};
        let mode = |name: &str, kind, contacts| MechanicalMode {
            name: name.to_string(),
            kind,
            stop: None,
            contacts,
            doc: String::new(),
        };
        let slip = MechanicalModeKind::Slip;
        let mut modes: Vec<MechanicalMode> = if shared {
            vec![
                mode("slip0", slip, Some(Vec::new())),
                mode("moving", slip, None),
                mode("stick0", MechanicalModeKind::Stick, Some(Vec::new())),
            ]
        } else {
            (0..1u32 << contacts.len())
                .map(|mask| {
                    let engaged = (0..contacts.len())
                        .filter(|i| mask & (1 << i) != 0)
                        .map(|i| names[i].clone())
                        .collect();
                    mode(&format!("slip{mask}"), slip, Some(engaged))
                })
                .collect()
        };
        modes.push(mode("stick", MechanicalModeKind::Stick, None));
        for stop in ["low", "high"] {
            modes.push(MechanicalMode {
                stop: Some(stop.to_string()),
                ..mode(stop, MechanicalModeKind::Stop, None)
            });
        }
        let m = MechanicalModel {
            name: "drawn".to_string(),
            position_unit: String::new(),
            internal_step: 0.0025 / 4.0,
            inputs: vec!["u".to_string()],
            parameters: vec![param("gain", gain), param("k", stiffness)],
            forces: vec![
                ForceElement::Input {
                    input: "u".to_string(),
                    gain: Quantity::Param("gain".to_string()),
                },
                ForceElement::Constant { value: q(constant) },
                ForceElement::Spring {
                    stiffness: Quantity::Param("k".to_string()),
                    rest: q(rest),
                },
                ForceElement::Damper {
                    coefficient: q(damping),
                },
            ],
            friction: hysid_mechanical::Friction {
                kinetic: q(friction[0]),
                static_level: q(friction[1]),
            },
            contacts: contacts
                .iter()
                .zip(&names)
                .map(
                    |(&(at, positive, k, d, f, unilateral), name)| hysid_mechanical::Contact {
                        name: name.clone(),
                        position: q(at),
                        direction: if positive {
                            Direction::Positive
                        } else {
                            Direction::Negative
                        },
                        stiffness: q(k),
                        damping: q(d),
                        friction: q(f),
                        unilateral,
                    },
                )
                .collect(),
            stops: [
                ("low", -4.0, Direction::Negative),
                ("high", 4.0, Direction::Positive),
            ]
            .into_iter()
            .zip(restitution)
            .map(|((name, at, direction), e)| hysid_mechanical::Stop {
                name: name.to_string(),
                position: q(at),
                direction,
                restitution: e,
            })
            .collect(),
            modes,
            initial_state: match given {
                Some((position, velocity)) => MechanicalInitialState::Given { position, velocity },
                None => MechanicalInitialState::Measured {
                    samples: 10,
                    velocity_tol: 0.0,
                },
            },
            info: Default::default(),
        };
        m.validate().unwrap();
        m
    }

    fn contact() -> impl Strategy<Value = ContactDraw> {
        (
            -3.0f64..3.0,
            any::<bool>(),
            0.0f64..2000.0,
            0.0f64..40.0,
            0.0f64..50.0,
            any::<bool>(),
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// The gray-box form of the head runs as the mechanical simulator
        /// runs the head, for parameters anywhere in their bounds.
        #[test]
        fn the_head_runs_alike_anywhere(
            z in proptest::collection::vec(0.0f64..=1.0, 12),
            seed in any::<u64>(),
            low in -0.3f64..-0.1,
        ) {
            let (worst, label, _, _) = compare(&head(&z), &record(seed, 600, low, 0.05, 3.0));
            prop_assert!(worst < 1e-9, "max |y difference| {}", worst);
            prop_assert_eq!(label, None);
        }

        /// Any mechanical structure: the same outputs (to 1e-6 of the stops'
        /// distance) and the same mode labels at every sample, on runs
        /// within the Zeno bound, from measured states or given ones (on a
        /// stop too, moving either way).
        #[test]
        fn any_structure_runs_alike(
            forces in (200.0f64..2000.0, -100.0f64..100.0, 0.0f64..400.0, -1.0f64..1.0, 0.0f64..10.0),
            friction in (0.0f64..150.0, 0.0f64..200.0),
            contacts in proptest::collection::vec(contact(), 0..=2),
            restitution in (prop_oneof![Just(0.0), 0.0f64..0.6], prop_oneof![Just(0.0), 0.0f64..0.6]),
            given in proptest::option::of((
                prop_oneof![-3.9f64..3.9, Just(-4.0), Just(4.0)],
                -20.0f64..20.0,
            )),
            shared in any::<bool>(),
            seed in any::<u64>(),
        ) {
            let (a, b, c, d, e) = forces;
            let m = drawn(
                [a, b, c, d, e],
                [friction.0, friction.1],
                &contacts,
                [restitution.0, restitution.1],
                given,
                shared,
            );
            let (worst, label, _, zeno) = compare(&m, &record(seed, 400, -1.0, 1.0, 0.5));
            // Past the Zeno bound the two differ by design: the mechanical
            // mass comes to rest, the gray-box stops hold their position.
            prop_assume!(zeno == 0);
            prop_assert!(worst < 1e-9, "max |y difference| {}", worst);
            prop_assert_eq!(label, None);
        }
    }

    #[test]
    fn names_of_the_model_are_kept_apart() {
        let contact = (1.0, true, 800.0, 10.0, 20.0, true);
        let mut m = drawn(
            [900.0, 10.0, 100.0, 0.0, 2.0],
            [30.0, 40.0],
            &[contact],
            [0.0; 2],
            None,
            false,
        );
        for name in ["y", "v", "F", "p_c0", "lambda_c0"] {
            let mut p = m.parameters[0].clone();
            p.name = name.to_string();
            m.parameters.push(p);
        }
        let g = to_gray_box(&m).unwrap();
        assert_eq!(g.states, ["y_", "v_"]);
        assert!(g.definitions.contains_key("F_") && g.definitions.contains_key("lambda_c0_"));
        let (worst, label, events, _) = compare(&m, &record(3, 400, -1.0, 1.0, 0.5));
        assert!(
            worst < 1e-9 && label.is_none() && events > 0,
            "{worst} {label:?} {events}"
        );
    }

    /// The wall of docs/mechanical-models.md ("Writing another system"),
    /// bouncing with restitution 0.5.
    fn wall() -> MechanicalModel {
        let text = r#"
kind = "mechanical"
internal_step = 0.0005
inputs = ["force"]
initial_state = { from = "measured", samples = 5 }
parameters = [
  { name = "k", value = 100.0, bounds = [10.0, 1000.0] },
  { name = "mu", value = 2.0, bounds = [0.0, 10.0] },
]
forces = [
  { type = "input", input = "force", gain = 1.0 },
  { type = "spring", stiffness = "k" },
]
friction = { kinetic = "mu", static = "mu" }
stops = [{ name = "wall", position = -0.1, direction = "negative", restitution = 0.5 }]
modes = [
  { name = "at_wall", kind = "stop", stop = "wall" },
  { name = "moving", kind = "slip" },
  { name = "stuck", kind = "stick" },
]
"#;
        match crate::model::Model::from_toml(text, "wall.toml") {
            Ok(crate::model::Model::Mechanical(m)) => m,
            other => panic!("{other:?}"),
        }
    }

    /// Starts the reference takes too: a state given on a stop and moving
    /// away leaves it, a measured warm-up of 0 samples reads one, and a
    /// stop pressed by a bouncing mass holds it past the Zeno bound (the
    /// wall pushed with -30, where every sub-step of a sample meets it).
    #[test]
    fn starts_on_stops_and_the_zeno_bound_run_alike() {
        let mut away = wall();
        away.initial_state = MechanicalInitialState::Given {
            position: -0.1,
            velocity: 1.0,
        };
        let mut none = wall();
        none.initial_state = MechanicalInitialState::Measured {
            samples: 0,
            velocity_tol: 0.0,
        };
        for (m, low, zeno_expected) in [
            (away, -1.0, false),
            (none, -1.0, false),
            (wall(), -30.0, true),
        ] {
            let data = record(1, 800, low, 10.0, 0.0);
            let (worst, label, _, zeno) = compare(&m, &data);
            assert!(worst < 1e-9 && label.is_none(), "{worst} {label:?}");
            assert_eq!(zeno > 0, zeno_expected, "{zeno} Zeno steps");
        }
    }

    /// One-step prediction reads every state from the measured outputs,
    /// as the reference's does, whatever the initial-state rule.
    #[test]
    fn predictions_run_alike() {
        let run = hysid_mechanical::simulate::run(
            &wall(),
            &wall().values(),
            &record(2, 600, -5.0, 5.0, 0.0),
        )
        .unwrap();
        let data = Dataset::siso(
            record(2, 600, -5.0, 5.0, 0.0).u(0).to_vec(),
            run.y,
            Some(0.0025),
        )
        .unwrap();
        let mut given = wall();
        given.initial_state = MechanicalInitialState::Given {
            position: 0.0,
            velocity: 0.0,
        };
        for m in [wall(), given] {
            let a = crate::simulate::predict(
                &crate::model::Model::Mechanical(m.clone()),
                &data,
                Default::default(),
            )
            .unwrap();
            let b = hysid_mechanical::simulate::predict(&m, &data).unwrap();
            let worst =
                a.y.iter()
                    .zip(&b.y)
                    .map(|(p, q)| (p - q).abs())
                    .fold(0.0, f64::max);
            assert!(
                worst < 1e-9 && a.modes == b.modes && a.start == b.start,
                "{worst}"
            );
        }
    }

    /// An input whose name is no gray-box name takes a fresh one (inputs
    /// are read by position); a parameter's name is the priors' and the
    /// diagnostics' key, so one that is no gray-box name is refused.
    #[test]
    fn input_names_are_made_names_parameter_names_must_be() {
        let mut m = head(&[0.5; 12]);
        m.inputs = vec!["motor u [V]".to_string()];
        for f in &mut m.forces {
            if let ForceElement::Input { input, .. } = f {
                *input = "motor u [V]".to_string();
            }
        }
        let g = to_gray_box(&m).unwrap();
        assert_eq!(g.inputs, ["u1"]);
        let (worst, label, events, _) = compare(&m, &record(1, 1200, -0.3, 0.05, 3.0));
        assert!(worst < 1e-9 && label.is_none() && events > 0);
        let mut m = head(&[0.5; 12]);
        m.parameters[0].name = "k-u".to_string();
        for f in &mut m.forces {
            if let ForceElement::Input { gain, .. } = f {
                *gain = Quantity::Param("k-u".to_string());
            }
        }
        let Err(Untranslatable::GrayBox(e)) = to_gray_box(&m) else {
            panic!("a parameter named 'k-u' translated")
        };
        assert!(e.to_string().contains("'k-u' is not a valid name"), "{e}");
    }

    /// Regimes labelled alike, and stuck regimes labelled by their
    /// contacts, keep the mechanical labels in the gray-box form (the
    /// `label` and `element_modes` of its modes).
    #[test]
    fn shared_and_contact_labels_run_alike() {
        use hysid_mechanical::{MechanicalMode, MechanicalModeKind};
        // One slip mode for sliding free and in contact with the board.
        let mut shared = head(&[0.5; 12]);
        shared.modes.retain(|q| q.name != "impact");
        let free = shared.modes.iter_mut().find(|q| q.name == "free").unwrap();
        free.contacts = None;
        // Stuck in contact labelled apart from stuck free, by a mode
        // whose name is no gray-box name.
        let mut by_contacts = head(&[0.5; 12]);
        by_contacts.modes.insert(
            0,
            MechanicalMode {
                name: "stuck on board".to_string(),
                kind: MechanicalModeKind::Stick,
                stop: None,
                contacts: Some(vec!["board".to_string()]),
                doc: String::new(),
            },
        );
        for (m, labels) in [
            (&shared, ["free", "free", "stick"]),
            (&by_contacts, ["free", "impact", "stick"]),
        ] {
            let g = to_gray_box(m).unwrap();
            let free_then_contact: Vec<&str> = g.modes.iter().map(|q| q.label()).collect();
            assert_eq!(free_then_contact, labels[..2]);
            assert_eq!(g.elements.last().unwrap().mode(), labels[2]);
            let mut seen = 0;
            for seed in 0..5 {
                let data = record(seed, 1200, -0.3, 0.05, 3.0);
                let (worst, label, events, _) = compare(m, &data);
                assert!(
                    worst < 1e-9 && label.is_none() && events > 0,
                    "seed {seed}: {worst} {label:?} {events}"
                );
                let c = CompiledModel::new(&g).unwrap();
                let run = hysid_graybox::simulate::run(&c, &g.values(), &data).unwrap();
                seen |= run.modes.iter().flatten().fold(0u32, |a, &i| a | 1 << i);
            }
            // Every label of the form was reached at least once.
            assert_eq!(
                seen,
                (1 << g.mode_names().len()) - 1,
                "{:?}",
                g.mode_names()
            );
        }
        let g = to_gray_box(&by_contacts).unwrap();
        assert_eq!(g.modes[1].element_modes["friction"], "stuck on board");
    }

    /// A damping-only contact whose force changes sign with the velocity,
    /// at the stop where the mass rests or rebounds: it lets go the instant
    /// the mass leaves the stop or rebounds from it, where the stop's reset
    /// jumps the contact force across zero (the release guard fires across
    /// the jump). Found by the property test above.
    #[test]
    fn a_contact_lets_go_as_the_mass_leaves_or_rebounds_from_a_stop() {
        let contact = (0.0, false, 0.0, 12.017605113916371, 0.0, true);
        for (restitution, seed) in [(0.0, 665_781_310_308), (0.35939584250215173, 19317)] {
            let m = drawn(
                [1929.4643903193862, 0.0, 0.0, 0.0, 0.0],
                [0.0; 2],
                &[contact],
                [restitution, 0.0],
                None,
                false,
            );
            let (worst, label, _, zeno) = compare(&m, &record(seed, 400, -1.0, 1.0, 0.5));
            assert!(
                worst < 1e-9 && label.is_none() && (restitution > 0.0 || zeno == 0),
                "e = {restitution}: {worst} {label:?} {zeno}"
            );
        }
    }
}
