//! Python pickles of numpy arrays in plain containers, for the consumers that read pickles
//! (TripoSG's `np.load(path, allow_pickle=True).tolist()`, TRELLIS.2's mesh dumps). Protocol 4,
//! and each array is `numpy.ndarray(shape, descr, buffer)` over its bytes, so no numpy-internal
//! name (`numpy.core` vs `numpy._core`) is written: any numpy from 1.x to 2.x loads it. The
//! arrays come back read-only (their buffer is a `bytes`); the consumers copy or index them.

/// A value to pickle.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// A `str`.
    Text(String),
    /// A numpy array: `descr` (`<f4`, `<i4`), shape, little-endian element bytes.
    Array {
        /// numpy type string.
        descr: &'static str,
        /// Shape.
        shape: Vec<usize>,
        /// Row-major element bytes.
        data: Vec<u8>,
    },
    /// A `list`.
    List(Vec<Value>),
    /// A `dict` with `str` keys, in this order.
    Dict(Vec<(String, Value)>),
    /// `numpy.array(value, 'O')`: a 0-d object array holding the value (what `np.save` of a
    /// dict stores, and what `.tolist()` gives back).
    ObjectArray(Box<Value>),
}

/// The pickle (protocol 4) of `value`.
pub fn dumps(value: &Value) -> Vec<u8> {
    let mut out = vec![0x80, 4]; // PROTO 4
    write(&mut out, value);
    out.push(b'.'); // STOP
    out
}

/// The `.npy` file `np.save` writes for an object array: a `|O` header of shape `()`, then
/// the pickle of `value` (an [`Value::ObjectArray`]).
pub fn npy_of_object(value: &Value) -> Vec<u8> {
    let mut header = "{'descr': '|O', 'fortran_order': False, 'shape': (), }".to_string();
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(&dumps(value));
    out
}

fn write(out: &mut Vec<u8>, value: &Value) {
    match value {
        Value::Text(s) => text(out, s),
        Value::Array { descr, shape, data } => {
            global(out, "numpy", "ndarray");
            out.push(b'('); // MARK
            out.push(b'(');
            for &d in shape {
                int(out, d as i64);
            }
            out.push(b't'); // TUPLE
            text(out, descr);
            out.push(0x8e); // BINBYTES8
            out.extend_from_slice(&(data.len() as u64).to_le_bytes());
            out.extend_from_slice(data);
            out.push(b't');
            out.push(b'R'); // REDUCE
        }
        Value::List(items) => {
            out.push(b']'); // EMPTY_LIST
            if !items.is_empty() {
                out.push(b'(');
                for v in items {
                    write(out, v);
                }
                out.push(b'e'); // APPENDS
            }
        }
        Value::Dict(entries) => {
            out.push(b'}'); // EMPTY_DICT
            if !entries.is_empty() {
                out.push(b'(');
                for (k, v) in entries {
                    text(out, k);
                    write(out, v);
                }
                out.push(b'u'); // SETITEMS
            }
        }
        Value::ObjectArray(inner) => {
            global(out, "numpy", "array");
            out.push(b'(');
            write(out, inner);
            text(out, "O");
            out.push(b't');
            out.push(b'R');
        }
    }
}

/// `module.name` pushed by STACK_GLOBAL.
fn global(out: &mut Vec<u8>, module: &str, name: &str) {
    text(out, module);
    text(out, name);
    out.push(0x93); // STACK_GLOBAL
}

fn text(out: &mut Vec<u8>, s: &str) {
    let b = s.as_bytes();
    if b.len() < 256 {
        out.push(0x8c); // SHORT_BINUNICODE
        out.push(b.len() as u8);
    } else {
        out.push(0x8d); // BINUNICODE8
        out.extend_from_slice(&(b.len() as u64).to_le_bytes());
    }
    out.extend_from_slice(b);
}

fn int(out: &mut Vec<u8>, i: i64) {
    match i32::try_from(i) {
        Ok(small) => {
            out.push(b'J'); // BININT
            out.extend_from_slice(&small.to_le_bytes());
        }
        Err(_) => {
            out.push(0x8a); // LONG1
            out.push(8);
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
}

/// An `f32` array `[rows, 3]` of `values` (flattened rows).
pub fn f32_rows(values: &[f64], columns: usize) -> Value {
    let data: Vec<u8> = values
        .iter()
        .flat_map(|&x| (x as f32).to_le_bytes())
        .collect();
    Value::Array {
        descr: "<f4",
        shape: vec![values.len() / columns.max(1), columns],
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dict_of_arrays_pickles_to_the_expected_opcodes() {
        let v = Value::Dict(vec![("a".into(), f32_rows(&[1.0, 2.0, 3.0], 3))]);
        let p = dumps(&v);
        assert_eq!(&p[..3], &[0x80, 4, b'}']);
        assert_eq!(*p.last().unwrap_or(&0), b'.');
        // The array's 12 bytes follow BINBYTES8 and its length.
        let at = p.iter().position(|&b| b == 0x8e).unwrap_or(0);
        assert_eq!(&p[at + 1..at + 9], &12u64.to_le_bytes());
        assert_eq!(&p[at + 9..at + 13], &1.0f32.to_le_bytes());
    }
}
