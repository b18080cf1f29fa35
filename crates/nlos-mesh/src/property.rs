//! Named, typed per-element property arrays (pmp's `PropertyContainer`).
//!
//! Each element kind (vertex, edge, face) has a container of arrays that grow with the element arrays and
//! are compacted by [`crate::SurfaceMesh::garbage_collect`]. A property is created with a name and a
//! default value and accessed through a typed handle such as [`VertexProperty<T>`].

use std::any::Any;
use std::fmt;
use std::marker::PhantomData;

/// Object-safe view of one property array.
pub(crate) trait PropertyArray: fmt::Debug + Send + Sync {
    fn push_default(&mut self);
    fn retain_mask(&mut self, keep: &[bool]);
    fn len(&self) -> usize;
    fn clone_box(&self) -> Box<dyn PropertyArray>;
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

#[derive(Debug, Clone)]
struct TypedArray<T> {
    data: Vec<T>,
    default: T,
}

impl<T: Clone + fmt::Debug + Send + Sync + 'static> PropertyArray for TypedArray<T> {
    fn push_default(&mut self) {
        self.data.push(self.default.clone());
    }
    fn retain_mask(&mut self, keep: &[bool]) {
        let mut i = 0;
        self.data.retain(|_| {
            let k = keep.get(i).copied().unwrap_or(false);
            i += 1;
            k
        });
    }
    fn len(&self) -> usize {
        self.data.len()
    }
    fn clone_box(&self) -> Box<dyn PropertyArray> {
        Box::new(self.clone())
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// The property arrays of one element kind. Removed properties leave a tombstone so that handles to the
/// others stay valid.
#[derive(Debug, Default)]
pub(crate) struct PropertyContainer {
    slots: Vec<Option<(String, Box<dyn PropertyArray>)>>,
}

impl Clone for PropertyContainer {
    fn clone(&self) -> Self {
        Self { slots: self.slots.iter().map(|s| s.as_ref().map(|(n, a)| (n.clone(), a.clone_box()))).collect() }
    }
}

impl PropertyContainer {
    pub(crate) fn add<T: Clone + fmt::Debug + Send + Sync + 'static>(
        &mut self,
        name: &str,
        default: T,
        len: usize,
    ) -> Option<usize> {
        if self.find(name).is_some() {
            return None;
        }
        let arr = TypedArray { data: vec![default.clone(); len], default };
        self.slots.push(Some((name.to_owned(), Box::new(arr))));
        Some(self.slots.len() - 1)
    }

    pub(crate) fn find(&self, name: &str) -> Option<usize> {
        self.slots.iter().position(|s| s.as_ref().is_some_and(|(n, _)| n == name))
    }

    pub(crate) fn find_typed<T: 'static>(&self, name: &str) -> Option<usize> {
        let i = self.find(name)?;
        self.get::<T>(i).map(|_| i)
    }

    pub(crate) fn remove(&mut self, slot: usize) -> bool {
        match self.slots.get_mut(slot) {
            Some(s @ Some(_)) => {
                *s = None;
                true
            }
            _ => false,
        }
    }

    pub(crate) fn get<T: 'static>(&self, slot: usize) -> Option<&[T]> {
        let (_, arr) = self.slots.get(slot)?.as_ref()?;
        arr.as_any().downcast_ref::<TypedArray<T>>().map(|a| a.data.as_slice())
    }

    pub(crate) fn get_mut<T: 'static>(&mut self, slot: usize) -> Option<&mut [T]> {
        let (_, arr) = self.slots.get_mut(slot)?.as_mut()?;
        arr.as_any_mut().downcast_mut::<TypedArray<T>>().map(|a| a.data.as_mut_slice())
    }

    pub(crate) fn push_default(&mut self) {
        for (_, a) in self.slots.iter_mut().flatten() {
            a.push_default();
        }
    }

    pub(crate) fn retain_mask(&mut self, keep: &[bool]) {
        for (_, a) in self.slots.iter_mut().flatten() {
            a.retain_mask(keep);
        }
    }

    pub(crate) fn names(&self) -> Vec<String> {
        self.slots.iter().flatten().map(|(n, _)| n.clone()).collect()
    }

    pub(crate) fn lengths_ok(&self, len: usize) -> bool {
        self.slots.iter().flatten().all(|(_, a)| a.len() == len)
    }
}

macro_rules! prop_handle {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Debug)]
        pub struct $name<T> {
            pub(crate) slot: usize,
            _marker: PhantomData<fn() -> T>,
        }
        impl<T> $name<T> {
            pub(crate) fn new(slot: usize) -> Self {
                Self { slot, _marker: PhantomData }
            }
        }
        impl<T> Clone for $name<T> {
            fn clone(&self) -> Self {
                *self
            }
        }
        impl<T> Copy for $name<T> {}
    };
}

prop_handle!(
    /// Handle to a per-vertex property of type `T`. Valid until the property is removed.
    VertexProperty
);
prop_handle!(
    /// Handle to a per-edge property of type `T`. Valid until the property is removed.
    EdgeProperty
);
prop_handle!(
    /// Handle to a per-face property of type `T`. Valid until the property is removed.
    FaceProperty
);
