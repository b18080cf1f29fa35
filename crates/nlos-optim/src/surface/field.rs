//! Named, typed per-element fields: what a field's values are ([`FieldValue`]), how one is named with its
//! initial value ([`VertexField`], [`FaceField`]) and how its values are stored ([`Column`]).

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::adam::{Moments, ScalarMoments};

/// A value a field can hold: stored in a [`Column`] and carried through topology changes by
/// [`FieldValue::blend`].
pub trait FieldValue: Copy + PartialEq + std::fmt::Debug + 'static {
    /// The type's name in messages.
    const TYPE: &'static str;
    /// A column of these values.
    fn column(values: Vec<Self>, initial: Self) -> Column;
    /// The column's values, when it holds this type.
    fn of(column: &Column) -> Option<&ColumnOf<Self>>;
    /// The column's values, mutably, when it holds this type.
    fn of_mut(column: &mut Column) -> Option<&mut ColumnOf<Self>>;
    /// The value at a point between elements that hold `parts` (value, weight): the weighted sum for
    /// quantities (the weights are barycentric, ≥ 0 and summing to 1), the value of the heaviest part for
    /// flags.
    fn blend(parts: &[(Self, f32)]) -> Self;
}

/// The storage half of a [`FieldValue`] impl: its name and its [`Column`] variant.
macro_rules! stored_as {
    ($name:literal, $variant:ident) => {
        const TYPE: &'static str = $name;
        fn column(values: Vec<Self>, initial: Self) -> Column {
            Column::$variant(ColumnOf { values, initial })
        }
        fn of(column: &Column) -> Option<&ColumnOf<Self>> {
            if let Column::$variant(c) = column { Some(c) } else { None }
        }
        fn of_mut(column: &mut Column) -> Option<&mut ColumnOf<Self>> {
            if let Column::$variant(c) = column { Some(c) } else { None }
        }
    };
}

impl FieldValue for f64 {
    stored_as!("f64", Real);
    fn blend(parts: &[(Self, f32)]) -> Self {
        parts.iter().fold(0.0, |s, &(x, w)| s + f64::from(w) * x)
    }
}

impl FieldValue for DVec3 {
    stored_as!("DVec3", Vector);
    fn blend(parts: &[(Self, f32)]) -> Self {
        parts.iter().fold(DVec3::ZERO, |s, &(x, w)| s + f64::from(w) * x)
    }
}

impl FieldValue for bool {
    stored_as!("bool", Flag);
    fn blend(parts: &[(Self, f32)]) -> Self {
        parts.iter().fold((false, f32::NEG_INFINITY), |best, &(x, w)| if w > best.1 { (x, w) } else { best }).0
    }
}

impl FieldValue for Moments {
    stored_as!("Moments", Moments);
    /// Both moments interpolated; the second kept ≥ 0 against rounding.
    fn blend(parts: &[(Self, f32)]) -> Self {
        let (mut m, mut v) = (DVec3::ZERO, 0.0f64);
        for &(x, w) in parts {
            m += f64::from(w) * x.m;
            v += f64::from(w) * x.v;
        }
        Moments { m, v: v.max(0.0) }
    }
}

impl FieldValue for ScalarMoments {
    stored_as!("ScalarMoments", ScalarMoments);
    /// Both moments interpolated; the second kept ≥ 0 against rounding.
    fn blend(parts: &[(Self, f32)]) -> Self {
        let (mut m, mut v) = (0.0f64, 0.0f64);
        for &(x, w) in parts {
            m += f64::from(w) * x.m;
            v += f64::from(w) * x.v;
        }
        ScalarMoments { m, v: v.max(0.0) }
    }
}

/// The values of one field, one per element, and the value a new element starts with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ColumnOf<T> {
    /// One value per element, in element order.
    pub values: Vec<T>,
    /// The value of an appended element (and of every element when the field is created).
    pub initial: T,
}

/// One field's values, of any [`FieldValue`] type (as the checkpoint stores them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Column {
    /// Real numbers (f64, exact in checkpoints).
    Real(ColumnOf<f64>),
    /// Vectors (f64).
    Vector(ColumnOf<DVec3>),
    /// Flags.
    Flag(ColumnOf<bool>),
    /// Adam moments ([`Moments`]).
    Moments(ColumnOf<Moments>),
    /// A scalar's Adam moments ([`ScalarMoments`]).
    ScalarMoments(ColumnOf<ScalarMoments>),
}

impl Column {
    /// Values held.
    pub fn len(&self) -> usize {
        match self {
            Column::Real(c) => c.values.len(),
            Column::Vector(c) => c.values.len(),
            Column::Flag(c) => c.values.len(),
            Column::Moments(c) => c.values.len(),
            Column::ScalarMoments(c) => c.values.len(),
        }
    }

    /// Whether it holds no value.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The column over a new element set: element `i` takes what `sources[i]` says ([`super::Source`]).
    pub(super) fn remapped(&self, sources: &[super::Source]) -> Column {
        fn each<T: FieldValue>(c: &ColumnOf<T>, sources: &[super::Source]) -> Column {
            T::column(sources.iter().map(|s| s.value(&c.values, c.initial)).collect(), c.initial)
        }
        match self {
            Column::Real(c) => each(c, sources),
            Column::Vector(c) => each(c, sources),
            Column::Flag(c) => each(c, sources),
            Column::Moments(c) => each(c, sources),
            Column::ScalarMoments(c) => each(c, sources),
        }
    }

    /// Whether every value is finite (flags always are).
    pub(super) fn is_finite(&self) -> bool {
        match self {
            Column::Real(c) => c.values.iter().chain([&c.initial]).all(|x| x.is_finite()),
            Column::Vector(c) => c.values.iter().chain([&c.initial]).all(|x| x.is_finite()),
            Column::Flag(_) => true,
            Column::Moments(c) => c.values.iter().chain([&c.initial]).all(|x| x.m.is_finite() && x.v.is_finite()),
            Column::ScalarMoments(c) => c.values.iter().chain([&c.initial]).all(|x| x.m.is_finite() && x.v.is_finite()),
        }
    }
}

macro_rules! field_handle {
    ($(#[$doc:meta])* $name:ident, $kind:literal) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct $name<T> {
            /// The field's name (its key in the checkpoint).
            pub name: &'static str,
            /// The value of an element the field has not seen: every element when it is created, an
            /// appended one later.
            pub initial: T,
        }

        impl<T: FieldValue> $name<T> {
            /// A field named `name` whose elements start at `initial`.
            pub const fn new(name: &'static str, initial: T) -> Self {
                Self { name, initial }
            }

            /// The element kind, in messages.
            pub(super) const KIND: &'static str = $kind;
        }
    };
}

field_handle!(
    /// A per-vertex field of [`super::Surface`]: declared once as a constant where it is used, created with
    /// its initial value on first write, carried through every topology change ([`super::Remap`]).
    VertexField,
    "vertex"
);
field_handle!(
    /// A per-face field of [`super::Surface`] (as [`VertexField`], per triangle).
    FaceField,
    "face"
);
