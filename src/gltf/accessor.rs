//! Reading the components of accessors.

use super::json;
use json::accessor::ComponentType;

/// How to read the components of an accessor.
#[derive(Debug, Clone, Copy)]
pub(super) struct Layout {
    pub component: ComponentType,
    pub components: usize,
}

impl Layout {
    pub fn component_size(self) -> usize {
        match self.component {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::U32 | ComponentType::F32 => 4,
        }
    }
    pub fn element_size(self) -> usize {
        self.component_size() * self.components
    }
}

/// Reads a little-endian `u32` from the first four bytes (the caller checks the length).
pub(super) fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

/// Reads component `b` (of `component`'s size) as a float, normalized if asked.
pub(super) fn component_f32(component: ComponentType, normalized: bool, b: &[u8]) -> f32 {
    match (component, normalized) {
        (ComponentType::F32, _) => f32::from_bits(le_u32(b)),
        (ComponentType::I8, false) => f32::from(b[0] as i8),
        (ComponentType::I8, true) => (f32::from(b[0] as i8) / 127.0).max(-1.0),
        (ComponentType::U8, false) => f32::from(b[0]),
        (ComponentType::U8, true) => f32::from(b[0]) / 255.0,
        (ComponentType::I16, false) => f32::from(i16::from_le_bytes([b[0], b[1]])),
        (ComponentType::I16, true) => {
            (f32::from(i16::from_le_bytes([b[0], b[1]])) / 32767.0).max(-1.0)
        }
        (ComponentType::U16, false) => f32::from(u16::from_le_bytes([b[0], b[1]])),
        (ComponentType::U16, true) => f32::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0,
        // Not accepted for positions; kept total for safety.
        (ComponentType::U32, false) => le_u32(b) as f32,
        (ComponentType::U32, true) => le_u32(b) as f32 / u32::MAX as f32,
    }
}

/// Reads an unsigned index component.
pub(super) fn component_u32(component: ComponentType, b: &[u8]) -> u32 {
    match component {
        ComponentType::U8 | ComponentType::I8 => u32::from(b[0]),
        ComponentType::U16 | ComponentType::I16 => u32::from(u16::from_le_bytes([b[0], b[1]])),
        ComponentType::U32 | ComponentType::F32 => le_u32(b),
    }
}

/// An accessor's element count.
pub(super) fn count(accessor: &json::Accessor) -> u64 {
    accessor.count.0
}

/// `n` tightly packed elements of `size` bytes from byte `offset` of `data`, if they fit.
pub(super) fn slice_at(data: &[u8], offset: u64, n: usize, size: usize) -> Option<&[u8]> {
    let start = usize::try_from(offset).ok()?;
    let end = n.checked_mul(size)?.checked_add(start)?;
    data.get(start..end)
}
