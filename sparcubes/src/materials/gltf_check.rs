//! What the `gltf` crate's readers assume of an accessor, checked before they are called.
//!
//! Its `read_colors`, `read_tex_coords` and `read_indices` end in `unreachable!()` for a
//! component type or type glTF does not allow there, and its accessor iterator slices and
//! asserts without checking the element size, the stride or the arithmetic of the span
//! (issue 61: a `COLOR_0` accessor of type `SCALAR` panicked inside the appearance reader
//! and failed an item whose shape converts). Validation of the document does not cover any of
//! this, so each accessor the appearance reads is checked here first; one that fails is named
//! as not read and left out, and the crate's reader only ever sees what it can read.

use gltf::accessor::{DataType, Dimensions};

/// A component type with a type.
pub(super) type Kind = (DataType, Dimensions);

/// What vertex colours may be (glTF 2.0 §3.7.2.1): VEC3 or VEC4 of unsigned byte, unsigned
/// short (both normalized) or float.
pub(super) const COLOURS: &[Kind] = &[
    (DataType::U8, Dimensions::Vec3),
    (DataType::U16, Dimensions::Vec3),
    (DataType::F32, Dimensions::Vec3),
    (DataType::U8, Dimensions::Vec4),
    (DataType::U16, Dimensions::Vec4),
    (DataType::F32, Dimensions::Vec4),
];

/// What texture coordinates may be: VEC2 of unsigned byte, unsigned short or float.
pub(super) const TEX_COORDS: &[Kind] = &[
    (DataType::U8, Dimensions::Vec2),
    (DataType::U16, Dimensions::Vec2),
    (DataType::F32, Dimensions::Vec2),
];

/// What indices may be: SCALAR of unsigned byte, short or int.
pub(super) const INDICES: &[Kind] = &[
    (DataType::U8, Dimensions::Scalar),
    (DataType::U16, Dimensions::Scalar),
    (DataType::U32, Dimensions::Scalar),
];

/// What positions are read as: VEC3 of float.
pub(super) const POSITIONS: &[Kind] = &[(DataType::F32, Dimensions::Vec3)];

/// Why the `gltf` crate cannot read `acc` as one of `allowed` from `buffers`, in words;
/// `None` when it can.
pub(super) fn unreadable(
    acc: &gltf::Accessor,
    allowed: &[Kind],
    buffers: &[Vec<u8>],
) -> Option<String> {
    let kind = (acc.data_type(), acc.dimensions());
    if !allowed.contains(&kind) {
        let can: Vec<String> = allowed.iter().map(|&k| kind_name(k)).collect();
        return Some(format!(
            "accessor {} is {}, not {}",
            acc.index(),
            kind_name(kind),
            can.join(", ")
        ));
    }
    let why = match (acc.view(), acc.sparse()) {
        (None, None) => Err("it has no buffer view".to_string()),
        (view, sparse) => view
            .map_or(Ok(()), |v| {
                fits(&v, acc.offset(), acc.count(), acc.size(), buffers)
            })
            .and_then(|()| sparse.map_or(Ok(()), |s| sparse_fits(&s, acc.size(), buffers))),
    };
    why.err().map(|w| format!("accessor {}: {w}", acc.index()))
}

/// Whether a sparse accessor's indices and values lie inside their buffer views.
fn sparse_fits(
    sparse: &gltf::accessor::sparse::Sparse,
    size: usize,
    buffers: &[Vec<u8>],
) -> Result<(), String> {
    let (indices, values) = (sparse.indices(), sparse.values());
    let index_size = indices.index_type().size();
    fits(
        &indices.view(),
        indices.offset(),
        sparse.count(),
        index_size,
        buffers,
    )
    .map_err(|w| format!("its sparse indices: {w}"))?;
    fits(
        &values.view(),
        values.offset(),
        sparse.count(),
        size,
        buffers,
    )
    .map_err(|w| format!("its sparse values: {w}"))
}

/// Whether `count` elements of `size` bytes from `offset` in `view`, at the view's stride,
/// lie inside the view and the view inside its buffer.
fn fits(
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    size: usize,
    buffers: &[Vec<u8>],
) -> Result<(), String> {
    let stride = view.stride().unwrap_or(size);
    if stride < size || size == 0 {
        return Err(format!(
            "its byte stride {stride} is less than its element size {size}"
        ));
    }
    let data = buffers
        .get(view.buffer().index())
        .ok_or("its buffer is missing")?;
    view.offset()
        .checked_add(view.length())
        .filter(|&end| end <= data.len())
        .ok_or("its buffer view runs past its buffer")?;
    let need = count
        .checked_sub(1)
        .ok_or("it has no elements")?
        .checked_mul(stride)
        .and_then(|n| n.checked_add(size))
        .and_then(|n| n.checked_add(offset));
    match need {
        Some(n) if n <= view.length() => Ok(()),
        _ => Err(format!(
            "its {count} elements run past its buffer view of {} bytes",
            view.length()
        )),
    }
}

/// A kind in glTF's words, `VEC2 of UNSIGNED_INT`.
fn kind_name((data, dims): Kind) -> String {
    let data = match data {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    };
    let dims = match dims {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    };
    format!("{dims} of {data}")
}
