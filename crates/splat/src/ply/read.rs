//! The PLY data section: locating the Gaussian properties in the `vertex`
//! element and decoding them from ascii or binary (either endianness).
//! Elements before `vertex` are skipped, those after it are ignored.

use std::path::Path;

use super::header::{parse_header, Element, Format, Property, ScalarType};
use super::{PlyError, PlyGaussians};

const VERTEX: &str = "vertex";
const F_REST_PREFIX: &str = "f_rest_";

/// Reads and parses a PLY file.
pub fn read_ply(path: &Path) -> Result<PlyGaussians, PlyError> {
    let bytes = std::fs::read(path).map_err(|source| PlyError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_ply(&bytes)
}

/// Parses the bytes of a PLY file. Never panics; a huge declared vertex count
/// is checked against the data actually present before anything is allocated.
pub fn parse_ply(bytes: &[u8]) -> Result<PlyGaussians, PlyError> {
    let header = parse_header(bytes)?;
    let elements = &header.elements;
    let vi = elements
        .iter()
        .position(|e| e.name == VERTEX)
        .ok_or_else(|| {
            let names: Vec<&str> = elements.iter().map(|e| e.name.as_str()).collect();
            PlyError::MissingVertexElement {
                found: if names.is_empty() {
                    "none".into()
                } else {
                    names.join(", ")
                },
            }
        })?;
    let fields = FieldMap::resolve(&elements[vi])?;
    let body = bytes.get(header.body_offset..).unwrap_or(&[]);
    match header.format {
        Format::Ascii => read_ascii(body, header.line_count, elements, vi, &fields),
        Format::BinaryLittleEndian => read_binary(body, false, elements, vi, &fields),
        Format::BinaryBigEndian => read_binary(body, true, elements, vi, &fields),
    }
}

/// Indices, within the vertex element's property list, of the values we keep.
struct FieldMap {
    mean: [usize; 3],
    dc: [usize; 3],
    opacity: usize,
    scale: [usize; 3],
    rot: [usize; 4],
    rest: Vec<usize>,
}

impl FieldMap {
    fn resolve(vertex: &Element) -> Result<Self, PlyError> {
        let props = &vertex.properties;
        let find = |name: &str| -> Result<usize, PlyError> {
            match props.iter().position(|p| p.name() == name) {
                Some(i) if matches!(props[i], Property::List { .. }) => {
                    Err(PlyError::UnexpectedList { name: name.into() })
                }
                Some(i) => Ok(i),
                None => {
                    let present: Vec<&str> = props.iter().map(Property::name).collect();
                    Err(PlyError::MissingProperty {
                        name: name.into(),
                        present: if present.is_empty() {
                            "none".into()
                        } else {
                            present.join(" ")
                        },
                    })
                }
            }
        };
        let mut rest: Vec<(usize, usize)> = Vec::new();
        for (i, p) in props.iter().enumerate() {
            let Some(n) = p.name().strip_prefix(F_REST_PREFIX) else {
                continue;
            };
            // Only canonical decimal numbers count ("f_rest_7", not "f_rest_07").
            let Ok(k) = n.parse::<usize>() else { continue };
            if k.to_string() != n {
                continue;
            }
            if let Property::List { .. } = p {
                return Err(PlyError::UnexpectedList {
                    name: p.name().into(),
                });
            }
            rest.push((k, i));
        }
        // Numeric sort: f_rest_10 comes after f_rest_9, not after f_rest_1.
        rest.sort_unstable();
        if let Some(missing) = rest
            .iter()
            .enumerate()
            .position(|(want, &(k, _))| k != want)
        {
            return Err(PlyError::NonContiguousFRest {
                missing,
                found: rest.iter().map(|&(k, _)| k).collect(),
            });
        }
        Ok(FieldMap {
            mean: [find("x")?, find("y")?, find("z")?],
            dc: [find("f_dc_0")?, find("f_dc_1")?, find("f_dc_2")?],
            opacity: find("opacity")?,
            scale: [find("scale_0")?, find("scale_1")?, find("scale_2")?],
            rot: [
                find("rot_0")?,
                find("rot_1")?,
                find("rot_2")?,
                find("rot_3")?,
            ],
            rest: rest.into_iter().map(|(_, i)| i).collect(),
        })
    }

    /// Appends one vertex, given all its scalar values indexed by property.
    fn push(
        &self,
        g: &mut PlyGaussians,
        vertex: usize,
        props: &[Property],
        slots: &[f64],
    ) -> Result<(), PlyError> {
        let get = |i: usize| -> Result<f32, PlyError> {
            let value = slots.get(i).copied().unwrap_or(f64::NAN);
            let v = value as f32;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(PlyError::NonFinite {
                    property: props.get(i).map_or("?", Property::name).to_owned(),
                    vertex,
                    value,
                })
            }
        };
        let get3 = |ix: [usize; 3]| -> Result<[f32; 3], PlyError> {
            Ok([get(ix[0])?, get(ix[1])?, get(ix[2])?])
        };
        g.means.push(get3(self.mean)?);
        g.f_dc.push(get3(self.dc)?);
        g.opacity_logit.push(get(self.opacity)?);
        g.log_scales.push(get3(self.scale)?);
        let r = self.rot;
        g.rotations
            .push([get(r[0])?, get(r[1])?, get(r[2])?, get(r[3])?]);
        g.f_rest.push(
            self.rest
                .iter()
                .map(|&i| get(i))
                .collect::<Result<_, _>>()?,
        );
        Ok(())
    }
}

fn with_capacity(n: usize) -> PlyGaussians {
    PlyGaussians {
        means: Vec::with_capacity(n),
        f_dc: Vec::with_capacity(n),
        f_rest: Vec::with_capacity(n),
        opacity_logit: Vec::with_capacity(n),
        log_scales: Vec::with_capacity(n),
        rotations: Vec::with_capacity(n),
    }
}

/// Bounds-checked reader over the binary data section.
struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl Cursor<'_> {
    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    /// Advances `n` bytes, or returns `None` (without moving) past the end.
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let end = self.pos.checked_add(n)?;
        let s = self.data.get(self.pos..end)?;
        self.pos = end;
        Some(s)
    }

    fn read(&mut self, ty: ScalarType) -> Option<f64> {
        let big = self.big_endian;
        let b = self.take(ty.size())?;
        macro_rules! num {
            ($t:ty) => {{
                let a = b.try_into().ok()?;
                (if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        Some(match ty {
            ScalarType::I8 => num!(i8),
            ScalarType::U8 => num!(u8),
            ScalarType::I16 => num!(i16),
            ScalarType::U16 => num!(u16),
            ScalarType::I32 => num!(i32),
            ScalarType::U32 => num!(u32),
            ScalarType::F32 => num!(f32),
            ScalarType::F64 => num!(f64),
        })
    }
}

fn truncated(e: &Element, index: usize, what: String) -> PlyError {
    PlyError::Truncated {
        element: e.name.clone(),
        index,
        count: e.count,
        what,
    }
}

/// Reads one binary item of `e`, storing scalars in `slots` (if given) and
/// skipping lists by their stored length.
fn read_binary_item(
    cur: &mut Cursor,
    e: &Element,
    index: usize,
    mut slots: Option<&mut [f64]>,
) -> Result<(), PlyError> {
    for (pi, p) in e.properties.iter().enumerate() {
        let ended = || truncated(e, index, format!("file ended in property `{}`", p.name()));
        match p {
            Property::Scalar { ty, .. } => {
                let v = cur.read(*ty).ok_or_else(ended)?;
                if let Some(slot) = slots.as_deref_mut().and_then(|s| s.get_mut(pi)) {
                    *slot = v;
                }
            }
            Property::List {
                count_ty,
                item_ty,
                name,
            } => {
                let n = cur.read(*count_ty).ok_or_else(ended)?;
                let invalid = || PlyError::InvalidListCount {
                    element: e.name.clone(),
                    index,
                    property: name.clone(),
                    value: n,
                };
                if n < 0.0 {
                    return Err(invalid());
                }
                let bytes = (n as usize)
                    .checked_mul(item_ty.size())
                    .ok_or_else(invalid)?;
                cur.take(bytes).ok_or_else(ended)?;
            }
        }
    }
    Ok(())
}

fn read_binary(
    body: &[u8],
    big_endian: bool,
    elements: &[Element],
    vi: usize,
    fields: &FieldMap,
) -> Result<PlyGaussians, PlyError> {
    let mut cur = Cursor {
        data: body,
        pos: 0,
        big_endian,
    };
    for e in &elements[..vi] {
        match e.fixed_stride() {
            Some(stride) => {
                let bytes = e.count.checked_mul(stride);
                if bytes.and_then(|b| cur.take(b)).is_none() {
                    return Err(truncated_fixed(e, stride, cur.remaining()));
                }
            }
            None => (0..e.count).try_for_each(|i| read_binary_item(&mut cur, e, i, None))?,
        }
    }
    let v = &elements[vi];
    // Check the declared count against the bytes present before allocating.
    if let Some(stride) = v.fixed_stride()
        && v.count
            .checked_mul(stride)
            .is_none_or(|b| b > cur.remaining())
    {
        return Err(truncated_fixed(v, stride, cur.remaining()));
    }
    let mut g = with_capacity(v.count.min(cur.remaining() / v.min_stride().max(1)));
    let mut slots = vec![0.0f64; v.properties.len()];
    for i in 0..v.count {
        read_binary_item(&mut cur, v, i, Some(&mut slots))?;
        fields.push(&mut g, i, &v.properties, &slots)?;
    }
    Ok(g)
}

/// The error for a fixed-stride element whose data runs out: names the first
/// item that is incomplete.
fn truncated_fixed(e: &Element, stride: usize, remaining: usize) -> PlyError {
    let index = remaining.checked_div(stride).unwrap_or(0);
    let left = remaining - index.saturating_mul(stride).min(remaining);
    truncated(
        e,
        index,
        format!("expected {stride} bytes, file ended ({left} left)"),
    )
}

fn read_ascii(
    body: &[u8],
    header_lines: usize,
    elements: &[Element],
    vi: usize,
    fields: &FieldMap,
) -> Result<PlyGaussians, PlyError> {
    // Non-blank lines with their 1-based line number in the whole file.
    let mut last_line = header_lines;
    let mut lines = body
        .split(|&b| b == b'\n')
        .enumerate()
        .map(|(i, l)| (header_lines + 1 + i, l))
        .filter(|(_, l)| !l.iter().all(u8::is_ascii_whitespace));
    let mut next_line = |e: &Element, index: usize| {
        let next = lines.next();
        if let Some((n, _)) = next {
            last_line = n;
        }
        next.ok_or_else(|| truncated(e, index, format!("file ended after line {last_line}")))
    };
    for e in &elements[..vi] {
        for i in 0..e.count {
            next_line(e, i)?;
        }
    }
    let v = &elements[vi];
    // Every ascii vertex takes at least two bytes ("0\n"), which bounds the
    // reservation no matter what count the header declares.
    let mut g = with_capacity(v.count.min(body.len() / 2));
    let mut slots = vec![0.0f64; v.properties.len()];
    for i in 0..v.count {
        let (line, text) = next_line(v, i)?;
        let mut tokens = text
            .split(u8::is_ascii_whitespace)
            .filter(|t| !t.is_empty());
        let mut next_number = |name: &str, integer: bool| -> Result<f64, PlyError> {
            let token = tokens.next().ok_or_else(|| PlyError::AsciiMissingValue {
                line,
                vertex: i,
                property: name.into(),
            })?;
            let bad = || PlyError::AsciiNumber {
                line,
                vertex: i,
                property: name.into(),
                text: String::from_utf8_lossy(token).into_owned(),
            };
            let s = std::str::from_utf8(token).map_err(|_| bad())?;
            if integer {
                s.parse::<i64>().map(|n| n as f64).map_err(|_| bad())
            } else {
                s.parse::<f64>().map_err(|_| bad())
            }
        };
        for (pi, p) in v.properties.iter().enumerate() {
            match p {
                Property::Scalar { name, ty } => slots[pi] = next_number(name, ty.is_integer())?,
                Property::List { name, item_ty, .. } => {
                    let n = next_number(name, true)?;
                    if n < 0.0 {
                        return Err(PlyError::InvalidListCount {
                            element: v.name.clone(),
                            index: i,
                            property: name.clone(),
                            value: n,
                        });
                    }
                    for _ in 0..n as u64 {
                        next_number(name, item_ty.is_integer())?;
                    }
                }
            }
        }
        if tokens.next().is_some() {
            return Err(PlyError::AsciiExtraValues { line, vertex: i });
        }
        fields.push(&mut g, i, &v.properties, &slots)?;
    }
    Ok(g)
}
