//! The definitions, modes, transitions, delays and energy of a model,
//! compiled into tapes with the definitions inlined.

use super::names::{mode_index, symbol_table};
use super::problem::{InvalidGrayBox, Problem, value};
use super::{CompiledMode, CompiledTransition, MAX_OPERATIONS};
use crate::expr::{
    DefinitionError, Definitions, ExprError, Expression, InlineError, Relation, Shared,
};
use crate::model::{Element, GrayBoxMode, GrayBoxModel, GrayBoxTransition};
use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::rc::Rc;

/// What compiling one model keeps at hand: the slots of its names, its
/// modes by name, the model's definitions (compiled when a mode first
/// reads them) and the operations compiled so far (at most
/// [`MAX_OPERATIONS`]).
pub(super) struct Compiler<'m> {
    m: &'m GrayBoxModel,
    /// Every definition name ([`super::names::definition_names`]).
    names: Vec<&'m String>,
    /// The slot of every name ([`super::names::symbol_table`]).
    symbols: HashMap<&'m str, usize>,
    pub(super) mode_index: BTreeMap<&'m str, usize>,
    /// Number of states: the first slots.
    pub(super) nx: usize,
    /// The slot of the first definition.
    first_def: usize,
    /// Per definition name, the model's text, if it gives one.
    model_texts: Vec<Option<&'m String>>,
    /// Per definition name, the model's text compiled, once a mode read it.
    model_definitions: Vec<Option<Rc<Expression>>>,
    /// The definitions only modes give: every mode must give them.
    mode_only: Vec<usize>,
    /// The slots the expressions other than definitions read, as written
    /// (recorded by [`Compiler::expr`] and [`Compiler::inlined`]).
    reads: RefCell<BTreeSet<u32>>,
    /// Per definition name, the slots its texts (the model's, the modes')
    /// read, as written.
    definition_reads: Vec<BTreeSet<u32>>,
    operations: usize,
}

impl<'m> Compiler<'m> {
    pub(super) fn new(m: &'m GrayBoxModel, names: Vec<&'m String>) -> Result<Self, InvalidGrayBox> {
        let symbols = symbol_table(m, &names)?;
        let mode_index = mode_index(m)?;
        // The model's definitions are the first names, in their order
        // ([`super::names::definition_names`]); the others only modes give.
        let model_texts: Vec<Option<&String>> = m
            .definitions
            .values()
            .map(Some)
            .chain(std::iter::repeat(None))
            .take(names.len())
            .collect();
        let mode_only = (0..names.len())
            .filter(|&i| model_texts[i].is_none())
            .collect();
        Ok(Compiler {
            nx: m.states.len(),
            first_def: m.states.len() + m.inputs.len() + m.parameters.len(),
            model_definitions: vec![None; names.len()],
            model_texts,
            mode_only,
            reads: RefCell::default(),
            definition_reads: vec![BTreeSet::new(); names.len()],
            names,
            symbols,
            mode_index,
            m,
            operations: 0,
        })
    }

    fn resolve(&self, n: &str) -> Option<u32> {
        self.symbols.get(n).map(|&slot| slot as u32)
    }

    /// The slot of the state `n` (the states take the first slots).
    pub(super) fn state_of(&self, place: &str, n: &str) -> Result<usize, InvalidGrayBox> {
        match self.symbols.get(n) {
            Some(&slot) if slot < self.nx => Ok(slot),
            _ => Err(InvalidGrayBox::new(
                place,
                Some(n),
                Problem::UnknownState(n.into()),
            )),
        }
    }

    pub(super) fn mode_of(&self, place: &str, n: &str) -> Result<usize, InvalidGrayBox> {
        self.mode_index
            .get(n)
            .copied()
            .ok_or_else(|| InvalidGrayBox::new(place, Some(n), Problem::UnknownMode(n.into())))
    }

    /// The parameters' slots.
    fn parameter_slots(&self) -> std::ops::Range<u32> {
        (self.nx + self.m.inputs.len()) as u32..self.first_def as u32
    }

    fn expr(&self, place: &str, text: &str) -> Result<Expression, InvalidGrayBox> {
        let e = self.expr_at(|| place.to_string(), text)?;
        self.reads.borrow_mut().extend(e.slots());
        Ok(e)
    }

    /// The definitions no expression reads, directly or through other
    /// definitions, in name order: a misspelt name, or an `extends` file's
    /// new entry where it meant to change the base's.
    pub(super) fn unread_definitions(&self) -> Vec<String> {
        let first = self.first_def as u32;
        let mut read = vec![false; self.names.len()];
        let mut pending: Vec<u32> = self.reads.borrow().iter().copied().collect();
        while let Some(slot) = pending.pop() {
            let Some(i) = slot.checked_sub(first).map(|i| i as usize) else {
                continue;
            };
            if i < read.len() && !read[i] {
                read[i] = true;
                pending.extend(&self.definition_reads[i]);
            }
        }
        let mut unread: Vec<String> = (self.names.iter().zip(&read))
            .filter(|(_, r)| !**r)
            .map(|(n, _)| n.to_string())
            .collect();
        unread.sort();
        unread
    }

    /// [`Compiler::expr`], with the place worded only for an error.
    fn expr_at(
        &self,
        place: impl FnOnce() -> String,
        text: &str,
    ) -> Result<Expression, InvalidGrayBox> {
        Expression::compile(text, &|n| self.resolve(n))
            .map_err(|e| InvalidGrayBox::new(place(), Some(text), e))
    }

    /// An expression of the parameters only.
    pub(super) fn parametric(&self, place: &str, text: &str) -> Result<Expression, InvalidGrayBox> {
        let e = value(place, text, self.expr(place, text)?)?;
        let params = self.parameter_slots();
        if e.slots().all(|s| params.contains(&s)) {
            Ok(e)
        } else {
            Err(InvalidGrayBox::new(
                place,
                Some(text),
                Problem::NotParametric(text.into()),
            ))
        }
    }

    /// The value of an expression of the parameters only at the file's
    /// values.
    pub(super) fn at_values(&self, e: &Expression) -> f64 {
        e.bind(self.parameter_slots().start, &self.m.values())
            .eval(&[])
    }

    /// A stop's restitution: parameters only, within `[0, 1)` over the
    /// parameters' bounds where it is affine in them (a number, a
    /// parameter, a scaled sum), at their values otherwise.
    pub(super) fn restitution(
        &self,
        place: &str,
        text: &str,
    ) -> Result<Expression, InvalidGrayBox> {
        let e = self.parametric(place, text)?;
        let first = self.parameter_slots().start;
        let parameter = |slot: u32| &self.m.parameters[(slot - first) as usize];
        let (low, high) = match e.affine() {
            Some((constant, terms)) => {
                terms
                    .iter()
                    .fold((constant, constant), |(low, high), &(slot, k)| {
                        let [a, b] = parameter(slot).bounds.map(|x| k * x);
                        (low + a.min(b), high + a.max(b))
                    })
            }
            None => {
                let v = self.at_values(&e);
                (v, v)
            }
        };
        if low >= 0.0 && high < 1.0 {
            Ok(e)
        } else {
            Err(InvalidGrayBox::new(
                place,
                Some(text),
                Problem::Restitution {
                    text: text.into(),
                    low,
                    high,
                },
            ))
        }
    }

    /// A mode's definitions, checked: every name has a value, no cycle,
    /// none too deep once written out.
    fn definitions_of(&mut self, q: &GrayBoxMode) -> Result<Definitions, InvalidGrayBox> {
        let place = format!("mode '{}'", q.name);
        // The mode's own values, by index (every name is in the table).
        let mut own: Vec<(usize, &String)> = q
            .definitions
            .iter()
            .filter_map(|(d, text)| {
                Some((
                    self.symbols.get(d.as_str())?.checked_sub(self.first_def)?,
                    text,
                ))
            })
            .collect();
        own.sort_unstable_by_key(|&(i, _)| i);
        let model_texts = &self.model_texts;
        let text_of = |i: usize| match own.binary_search_by_key(&i, |&(j, _)| j) {
            Ok(k) => Some(own[k].1),
            Err(_) => model_texts[i],
        };
        if let Some(&i) = self.mode_only.iter().find(|&&i| text_of(i).is_none()) {
            let d = self.names[i];
            let given_by = self.m.modes.iter().find(|q| q.definitions.contains_key(d));
            return Err(InvalidGrayBox::new(
                &place,
                Some(d),
                Problem::Undefined {
                    name: d.to_string(),
                    // A definition only modes give has a mode that gives it.
                    given_by: given_by.map_or_else(String::new, |q| q.name.clone()),
                },
            ));
        }
        let mut written = Vec::with_capacity(self.names.len());
        let mut mine = own.iter().peekable();
        for (i, d) in self.names.iter().enumerate() {
            let at = || format!("{place}, definition '{d}'");
            let e = match (mine.next_if(|&&(j, _)| j == i), self.model_texts[i]) {
                (Some((_, text)), _) => Rc::new(self.expr_at(at, text)?),
                (None, Some(text)) => match &self.model_definitions[i] {
                    Some(e) => Rc::clone(e),
                    None => {
                        let e = Rc::new(self.expr_at(at, text)?);
                        self.model_definitions[i] = Some(Rc::clone(&e));
                        e
                    }
                },
                (None, None) => unreachable!("every name only modes give is given above"),
            };
            self.definition_reads[i].extend(e.slots());
            written.push(e);
        }
        Definitions::new(self.first_def as u32, written).map_err(|e| match e {
            DefinitionError::Cycle(ring) => {
                // A ring of the model's own definitions is the model's
                // fault, whichever mode met it first.
                let in_mode = ring
                    .iter()
                    .any(|i| own.binary_search_by_key(i, |&(j, _)| j).is_ok());
                InvalidGrayBox::new(
                    if in_mode {
                        place.as_str()
                    } else {
                        "definitions"
                    },
                    Some(self.names[ring[0]]),
                    Problem::Cycle(ring.iter().map(|&i| self.names[i].to_string()).collect()),
                )
            }
            DefinitionError::TooDeep(i) => {
                let text = text_of(i).map_or("", String::as_str);
                InvalidGrayBox::new(
                    format!("{place}, definition '{}'", self.names[i]),
                    Some(text),
                    ExprError::TooDeep(text.to_string()),
                )
            }
        })
    }

    /// An expression of a mode with its definitions written in, counted
    /// into the operations compiled so far.
    fn inlined(
        &mut self,
        defs: &mut Definitions,
        place: &str,
        text: &str,
        e: Expression,
    ) -> Result<Expression, InvalidGrayBox> {
        self.reads.borrow_mut().extend(e.slots());
        let at = |problem: Problem| InvalidGrayBox::new(place, Some(text), problem);
        let e = e.inline(defs, MAX_OPERATIONS).map_err(|e| {
            at(match e {
                InlineError::TooDeep => ExprError::TooDeep(text.into()).into(),
                InlineError::TooLarge => ExprError::TooLarge(MAX_OPERATIONS).into(),
            })
        })?;
        self.operations += e.operations();
        if self.operations > MAX_OPERATIONS {
            return Err(at(Problem::TooLarge));
        }
        Ok(e)
    }

    /// The value `text` compiled in a mode whose definitions are `defs`.
    fn direct(
        &mut self,
        defs: &mut Definitions,
        place: &str,
        text: &str,
    ) -> Result<Expression, InvalidGrayBox> {
        let e = self.condition(defs, place, text)?;
        value(place, text, e)
    }

    /// [`Compiler::direct`] for a condition, which may be a relation.
    fn condition(
        &mut self,
        defs: &mut Definitions,
        place: &str,
        text: &str,
    ) -> Result<Expression, InvalidGrayBox> {
        let e = self.expr(place, text)?;
        self.inlined(defs, place, text, e)
    }

    fn direct_relation(
        &mut self,
        defs: &mut Definitions,
        place: &str,
        text: &str,
    ) -> Result<Relation, InvalidGrayBox> {
        let r = Relation::compile(text, &|n| self.resolve(n))
            .map_err(|e| InvalidGrayBox::new(place, Some(text), e))?;
        Ok(Relation {
            surface: self.inlined(defs, place, text, r.surface)?,
            crossing: r.crossing,
        })
    }

    /// Every mode with the transitions leaving it, each compiled with the
    /// definitions of the mode it leaves; the transitions' errors are
    /// reported in file order, after the modes'.
    pub(super) fn compile_modes(&mut self) -> Result<Vec<CompiledMode>, InvalidGrayBox> {
        let m = self.m;
        let mut leaving = vec![Vec::new(); m.modes.len()];
        for (i, t) in m.transitions.iter().enumerate() {
            if let Some(&from) = self.mode_index.get(t.from.as_str()) {
                leaving[from].push(i);
            }
        }
        let mut transitions: Vec<Option<Result<CompiledTransition, InvalidGrayBox>>> =
            vec![None; m.transitions.len()];
        // The definitions of the modes that give none of their own.
        let mut common: Option<Definitions> = None;
        let mut modes = Vec::with_capacity(m.modes.len());
        for (qi, q) in m.modes.iter().enumerate() {
            let mut own = None;
            if !q.definitions.is_empty() {
                own = Some(self.definitions_of(q)?);
            } else if common.is_none() {
                common = Some(self.definitions_of(q)?);
            }
            let Some(defs) = own.as_mut().or(common.as_mut()) else {
                unreachable!("a mode's definitions are made above");
            };
            modes.push(self.compile_mode(q, defs)?);
            for &i in &leaving[qi] {
                transitions[i] = Some(self.compile_transition(&m.transitions[i], defs));
            }
        }
        for (t, compiled) in m.transitions.iter().zip(transitions) {
            let place = format!("transition {} -> {}", t.from, t.to);
            let from = self.mode_of(&place, &t.from)?;
            let to = self.mode_of(&place, &t.to)?;
            let Some(compiled) = compiled else {
                unreachable!("every transition from a mode is compiled with it");
            };
            modes[from]
                .transitions
                .push(CompiledTransition { to, ..compiled? });
        }
        Ok(modes)
    }

    /// A mode's flows, invariant, friction levels and output (its
    /// transitions are added by [`Compiler::compile_modes`]).
    fn compile_mode(
        &mut self,
        q: &GrayBoxMode,
        defs: &mut Definitions,
    ) -> Result<CompiledMode, InvalidGrayBox> {
        let m = self.m;
        let place = format!("mode '{}'", q.name);
        // A key that is no state first: a misspelt state (`V` for `v`)
        // also leaves the state it meant without a flow.
        for s in q.flow.keys() {
            self.state_of(&format!("{place}, flow"), s)?;
        }
        let mut flow = Vec::with_capacity(self.nx);
        for s in &m.states {
            let text = q.flow.get(s).ok_or_else(|| {
                InvalidGrayBox::new(&place, Some(&q.name), Problem::MissingFlow(s.clone()))
            })?;
            flow.push(self.direct(defs, &format!("{place}, flow of '{s}'"), text)?);
        }
        let invariant = q
            .invariant
            .iter()
            .map(|t| self.direct_relation(defs, &format!("{place}, invariant"), t))
            .collect::<Result<_, _>>()?;
        let mut friction = Vec::with_capacity(m.elements.len());
        for e in &m.elements {
            friction.push(match e {
                Element::DryFriction {
                    kinetic,
                    static_level,
                    ..
                } => {
                    let at = format!("{place}, element '{}'", e.name());
                    (
                        self.direct(defs, &format!("{at}, kinetic"), kinetic)?,
                        self.direct(defs, &format!("{at}, static"), static_level)?,
                    )
                }
                Element::Stop { .. } => (Expression::constant(0.0), Expression::constant(0.0)),
            });
        }
        let output = &m.outputs[0];
        let output = self.direct(defs, &format!("output '{}'", output.name), &output.value)?;
        Ok(CompiledMode {
            joint_flow: Shared::of(&flow),
            flow,
            invariant,
            transitions: Vec::new(),
            friction,
            output,
        })
    }

    /// A transition's guard, condition and reset, in the definitions of
    /// the mode it leaves; `to` is set by [`Compiler::compile_modes`].
    fn compile_transition(
        &mut self,
        t: &GrayBoxTransition,
        defs: &mut Definitions,
    ) -> Result<CompiledTransition, InvalidGrayBox> {
        let place = format!("transition {} -> {}", t.from, t.to);
        let guard = self.direct_relation(defs, &format!("{place}, guard"), &t.guard)?;
        let signals = (self.nx + self.m.inputs.len()) as u32;
        if guard.surface.slots().all(|s| s >= signals) {
            let problem = Problem::FixedGuard(t.guard.clone());
            return Err(InvalidGrayBox::new(
                format!("{place}, guard"),
                Some(&t.guard),
                problem,
            ));
        }
        let when = t
            .when
            .as_deref()
            .map(|w| self.condition(defs, &format!("{place}, when"), w))
            .transpose()?;
        let mut reset = Vec::with_capacity(t.reset.len());
        for (s, text) in &t.reset {
            reset.push((
                self.state_of(&format!("{place}, reset"), s)?,
                self.direct(defs, &format!("{place}, reset of '{s}'"), text)?,
            ));
        }
        Ok(CompiledTransition {
            label: format!("{} -> {}", t.from, t.to),
            to: 0,
            guard,
            when,
            reset,
        })
    }

    /// Per input, its delay (parameters only; a constant 0 without one).
    pub(super) fn compile_delays(&self) -> Result<Vec<Expression>, InvalidGrayBox> {
        let m = self.m;
        let mut delays = vec![Expression::constant(0.0); m.inputs.len()];
        for (input, text) in &m.delays {
            let i = m.inputs.iter().position(|n| n == input).ok_or_else(|| {
                InvalidGrayBox::new("delays", Some(input), Problem::UnknownInput(input.clone()))
            })?;
            let place = format!("delays, input '{input}'");
            let delay = self.parametric(&place, text)?;
            if delay.as_constant().is_some_and(|d| !d.is_finite()) {
                let problem = Problem::NotFinite(format!("delays.{input}"));
                return Err(InvalidGrayBox::new(&place, Some(text), problem));
            }
            delays[i] = delay;
        }
        Ok(delays)
    }

    /// The stored energy: states and parameters only.
    pub(super) fn compile_energy(&self) -> Result<Option<Expression>, InvalidGrayBox> {
        let params = self.parameter_slots();
        self.m
            .energy
            .as_deref()
            .map(|text| {
                let e = value("energy", text, self.expr("energy", text)?)?;
                if e.slots()
                    .all(|s| (s as usize) < self.nx || params.contains(&s))
                {
                    Ok(e)
                } else {
                    Err(InvalidGrayBox::new(
                        "energy",
                        Some(text),
                        Problem::NotStateFunction(text.into()),
                    ))
                }
            })
            .transpose()
    }
}
