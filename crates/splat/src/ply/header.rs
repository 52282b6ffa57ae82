//! The PLY text header: everything up to and including the `end_header`
//! line, turned into a list of elements with typed properties. Knows nothing
//! about Gaussians.

use super::PlyError;

const MAGIC: &str = "ply";
const END_HEADER: &str = "end_header";
/// Quoted header lines are cut to this many characters in error messages, so
/// a binary blob that happens to start with `ply` cannot flood the terminal.
const MAX_QUOTED_LINE: usize = 120;

/// Encoding of the data section.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Format {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

/// Scalar property types, with both the classic and the sized spellings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarType {
    fn parse(name: &str) -> Option<Self> {
        use ScalarType::{F32, F64, I16, I32, I8, U16, U32, U8};
        Some(match name {
            "char" | "int8" => I8,
            "uchar" | "uint8" => U8,
            "short" | "int16" => I16,
            "ushort" | "uint16" => U16,
            "int" | "int32" => I32,
            "uint" | "uint32" => U32,
            "float" | "float32" => F32,
            "double" | "float64" => F64,
            _ => return None,
        })
    }

    /// Size in bytes in the binary encodings.
    pub(crate) fn size(self) -> usize {
        use ScalarType::{F32, F64, I16, I32, I8, U16, U32, U8};
        match self {
            I8 | U8 => 1,
            I16 | U16 => 2,
            I32 | U32 | F32 => 4,
            F64 => 8,
        }
    }

    pub(crate) fn is_integer(self) -> bool {
        !matches!(self, ScalarType::F32 | ScalarType::F64)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Property {
    Scalar {
        name: String,
        ty: ScalarType,
    },
    List {
        name: String,
        count_ty: ScalarType,
        item_ty: ScalarType,
    },
}

impl Property {
    pub(crate) fn name(&self) -> &str {
        match self {
            Property::Scalar { name, .. } | Property::List { name, .. } => name,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Element {
    pub name: String,
    pub count: usize,
    pub properties: Vec<Property>,
}

impl Element {
    /// Bytes per item when every property is a scalar; `None` with lists.
    pub(crate) fn fixed_stride(&self) -> Option<usize> {
        self.properties.iter().try_fold(0usize, |acc, p| match p {
            Property::Scalar { ty, .. } => acc.checked_add(ty.size()),
            Property::List { .. } => None,
        })
    }

    /// Fewest bytes one item can occupy (lists counted as empty); bounds how
    /// many items a data section of a given length can possibly contain.
    pub(crate) fn min_stride(&self) -> usize {
        self.properties
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => ty.size(),
                Property::List { count_ty, .. } => count_ty.size(),
            })
            .sum()
    }
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Header {
    pub format: Format,
    pub elements: Vec<Element>,
    /// Byte offset of the first data byte (just past `end_header\n`).
    pub body_offset: usize,
    /// Number of header lines, so ascii errors can report file line numbers.
    pub line_count: usize,
}

/// Parses the header at the start of `bytes`.
pub(crate) fn parse_header(bytes: &[u8]) -> Result<Header, PlyError> {
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut pos = 0usize;
    let mut line_no = 0usize;
    while pos < bytes.len() {
        let rest = &bytes[pos..];
        let (raw, next) = match rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&rest[..i], pos + i + 1),
            None => (rest, bytes.len()),
        };
        pos = next;
        line_no += 1;
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        if line_no == 1 {
            if raw != MAGIC.as_bytes() {
                return Err(PlyError::NotPly);
            }
            continue;
        }
        let malformed = |reason: &str| PlyError::MalformedHeader {
            line_no,
            line: quote(raw),
            reason: reason.to_owned(),
        };
        let line = std::str::from_utf8(raw).map_err(|_| malformed("not valid UTF-8 text"))?;
        let tokens: Vec<&str> = line.split_ascii_whitespace().collect();
        match tokens.as_slice() {
            [] | ["comment" | "obj_info", ..] => {}
            ["format", rest @ ..] => {
                if format.is_some() {
                    return Err(malformed("second format line"));
                }
                format = Some(match rest {
                    ["ascii", "1.0"] => Format::Ascii,
                    ["binary_little_endian", "1.0"] => Format::BinaryLittleEndian,
                    ["binary_big_endian", "1.0"] => Format::BinaryBigEndian,
                    _ => {
                        return Err(PlyError::UnsupportedFormat {
                            format: rest.join(" "),
                        })
                    }
                });
            }
            ["element", name, count] => {
                let count = count
                    .parse::<usize>()
                    .map_err(|_| malformed("element count is not a non-negative integer"))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["element", ..] => return Err(malformed("expected `element NAME COUNT`")),
            ["property", rest @ ..] => {
                let element = elements
                    .last_mut()
                    .ok_or_else(|| malformed("property before any element"))?;
                let property = match rest {
                    ["list", count_ty, item_ty, name] => {
                        let count_ty = ScalarType::parse(count_ty)
                            .filter(|t| t.is_integer())
                            .ok_or_else(|| malformed("list count type must be an integer type"))?;
                        let item_ty = ScalarType::parse(item_ty)
                            .ok_or_else(|| malformed("unknown property type"))?;
                        Property::List {
                            name: name.to_string(),
                            count_ty,
                            item_ty,
                        }
                    }
                    ["list", ..] => {
                        return Err(malformed(
                            "expected `property list COUNT_TYPE ITEM_TYPE NAME`",
                        ))
                    }
                    [ty, name] => Property::Scalar {
                        name: name.to_string(),
                        ty: ScalarType::parse(ty)
                            .ok_or_else(|| malformed("unknown property type"))?,
                    },
                    _ => return Err(malformed("expected `property TYPE NAME`")),
                };
                if element
                    .properties
                    .iter()
                    .any(|p| p.name() == property.name())
                {
                    return Err(malformed("duplicate property name"));
                }
                element.properties.push(property);
            }
            [END_HEADER] => {
                let format = format.ok_or_else(|| malformed("no format line before end_header"))?;
                return Ok(Header {
                    format,
                    elements,
                    body_offset: pos,
                    line_count: line_no,
                });
            }
            _ => return Err(malformed("unknown header keyword")),
        }
    }
    if line_no == 0 {
        return Err(PlyError::NotPly);
    }
    Err(PlyError::UnterminatedHeader)
}

/// Lossy, length-limited copy of a header line for error messages.
fn quote(raw: &[u8]) -> String {
    let text = String::from_utf8_lossy(raw);
    let mut out: String = text.chars().take(MAX_QUOTED_LINE).collect();
    if text.chars().count() > MAX_QUOTED_LINE {
        out.push_str("...");
    }
    out
}
