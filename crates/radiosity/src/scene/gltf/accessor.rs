//! Accessors (the glTF 2.0 specification's *Accessors* and *Sparse
//! Accessors*): typed views of a buffer view's bytes decoded into numbers,
//! normalized integers scaled as the specification says and floats widened
//! to the decimal they most likely were. Strides, offsets, element counts
//! and sparse indices are checked against the bytes present before any is
//! read, and every value must be finite. Each accessor is decoded once per
//! load, however many primitives share it.

use std::rc::Rc;

use gltf_json as json;
use json::validation::Checked;

use super::{Loader, SceneError, widen};

/// Most elements an accessor with no buffer view (all zeros, perhaps with
/// sparse substitutions) may declare: such an accessor costs memory without
/// any bytes in the file to back it.
pub const MAX_VIEWLESS_ELEMENTS: u64 = 1 << 22;

/// A decoded accessor: `components` numbers per element, row after row.
pub(super) struct Data {
    pub(super) values: Vec<f64>,
    components: usize,
}

impl Data {
    pub(super) fn count(&self) -> usize {
        self.values.len() / self.components.max(1)
    }

    pub(super) fn get(&self, element: usize) -> &[f64] {
        &self.values[element * self.components..(element + 1) * self.components]
    }
}

impl Loader<'_> {
    /// Decodes accessor `index` into numbers, checking that its type is one
    /// of `allowed` and that every byte it reads lies inside its buffer.
    pub(super) fn accessor(
        &self,
        index: usize,
        what: &str,
        allowed: &[json::accessor::Type],
    ) -> Result<Rc<Data>, SceneError> {
        use json::accessor::{ComponentType, Type};
        let accessors = &self.root.accessors;
        let accessor = accessors.get(index).ok_or_else(|| {
            self.error(format!(
                "{what} refers to accessor {index}, but the file has {}",
                accessors.len()
            ))
        })?;
        let what = format!("{what} accessor {index}");
        let Checked::Valid(kind) = accessor.type_ else {
            return Err(self.error(format!("{what} has an unknown type")));
        };
        if !allowed.contains(&kind) {
            return Err(self.error(format!(
                "{what} is {kind:?}, expected {}",
                allowed
                    .iter()
                    .map(|t| format!("{t:?}"))
                    .collect::<Vec<_>>()
                    .join(" or ")
            )));
        }
        let Checked::Valid(component) = accessor.component_type else {
            return Err(self.error(format!("{what} has an unknown component type")));
        };
        let component = component.0;
        let components = match kind {
            Type::Scalar => 1,
            Type::Vec2 => 2,
            Type::Vec3 => 3,
            Type::Vec4 => 4,
            Type::Mat2 | Type::Mat3 | Type::Mat4 => {
                return Err(self.error(format!("{what}: matrix accessors are not read")));
            }
        };
        if let Some(data) = self.decoded.borrow().get(&index) {
            return Ok(Rc::clone(data));
        }
        let size = component.size();
        let normalized = accessor.normalized;
        if normalized && matches!(component, ComponentType::U32 | ComponentType::F32) {
            return Err(self.error(format!(
                "{what} is normalized {component:?}, which glTF does not allow"
            )));
        }
        let decode = |b: &[u8]| -> f64 {
            match component {
                ComponentType::I8 => {
                    let v = f64::from(b[0] as i8);
                    if normalized { (v / 127.0).max(-1.0) } else { v }
                }
                ComponentType::U8 => {
                    let v = f64::from(b[0]);
                    if normalized { v / 255.0 } else { v }
                }
                ComponentType::I16 => {
                    let v = f64::from(i16::from_le_bytes([b[0], b[1]]));
                    if normalized {
                        (v / 32767.0).max(-1.0)
                    } else {
                        v
                    }
                }
                ComponentType::U16 => {
                    let v = f64::from(u16::from_le_bytes([b[0], b[1]]));
                    if normalized { v / 65535.0 } else { v }
                }
                ComponentType::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                ComponentType::F32 => widen(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            }
        };
        let count = accessor.count.0;
        let element = (components * size) as u64;
        // Reads `n` elements at `offset` with `stride` from a view, checked.
        let read = |view: usize,
                    offset: u64,
                    stride: Option<u64>,
                    n: u64,
                    element: u64,
                    part: &str|
         -> Result<&[u8], SceneError> {
            let bytes = self.view_bytes(view, &what)?;
            let stride = stride.unwrap_or(element);
            if stride < element {
                return Err(self.error(format!(
                    "{what}: {part} byte stride {stride} is smaller than an element ({element} \
                     bytes)"
                )));
            }
            let end = (n.max(1) - 1)
                .checked_mul(stride)
                .and_then(|v| v.checked_add(offset))
                .and_then(|v| v.checked_add(element));
            match end {
                Some(end) if n == 0 || end <= bytes.len() as u64 => {
                    Ok(&bytes[(offset as usize).min(bytes.len())..])
                }
                _ => Err(self.error(format!(
                    "{what}: {part} {n} elements of {element} bytes from byte {offset} run past \
                     the end of buffer view {view} ({} bytes)",
                    bytes.len()
                ))),
            }
        };
        let mut values;
        if let Some(view) = &accessor.buffer_view {
            let v = view.value();
            let stride = self
                .root
                .buffer_views
                .get(v)
                .and_then(|bv| bv.byte_stride)
                .map(|s| s.0 as u64);
            let offset = accessor.byte_offset.map_or(0, |o| o.0);
            let bytes = read(v, offset, stride, count, element, "its")?;
            let stride = stride.unwrap_or(element) as usize;
            values = Vec::with_capacity(count as usize * components);
            for e in 0..count as usize {
                let base = e * stride;
                for c in 0..components {
                    values.push(decode(&bytes[base + c * size..]));
                }
            }
        } else {
            if count > MAX_VIEWLESS_ELEMENTS {
                return Err(self.error(format!(
                    "{what} has no buffer view but declares {count} elements (at most \
                     {MAX_VIEWLESS_ELEMENTS})"
                )));
            }
            values = vec![0.0; count as usize * components];
        }
        if let Some(sparse) = &accessor.sparse {
            let n = sparse.count.0;
            if n > count {
                return Err(self.error(format!(
                    "{what}: {n} sparse substitutions for {count} elements"
                )));
            }
            let Checked::Valid(index_type) = sparse.indices.component_type else {
                return Err(self.error(format!("{what}: sparse indices of unknown type")));
            };
            let index_size = index_type.0.size() as u64;
            let index_bytes = read(
                sparse.indices.buffer_view.value(),
                sparse.indices.byte_offset.0,
                None,
                n,
                index_size,
                "sparse indices:",
            )?;
            let value_bytes = read(
                sparse.values.buffer_view.value(),
                sparse.values.byte_offset.0,
                None,
                n,
                element,
                "sparse values:",
            )?;
            let mut previous: Option<u64> = None;
            for k in 0..n as usize {
                let b = &index_bytes[k * index_size as usize..];
                let target = match index_size {
                    1 => u64::from(b[0]),
                    2 => u64::from(u16::from_le_bytes([b[0], b[1]])),
                    _ => u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                };
                if target >= count || previous.is_some_and(|p| target <= p) {
                    return Err(self.error(format!(
                        "{what}: sparse index {target} (entry {k}) is out of range or not \
                         increasing"
                    )));
                }
                previous = Some(target);
                for c in 0..components {
                    values[target as usize * components + c] =
                        decode(&value_bytes[(k * element as usize) + c * size..]);
                }
            }
        }
        if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
            return Err(self.error(format!(
                "{what}: element {} has a non-finite value ({})",
                bad / components,
                values[bad]
            )));
        }
        let data = Rc::new(Data { values, components });
        self.decoded.borrow_mut().insert(index, Rc::clone(&data));
        Ok(data)
    }
}
