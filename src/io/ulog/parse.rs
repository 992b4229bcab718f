//! Message framing, format definitions and field decoding (PX4's ULog file format;
//! pyulog `core.py`).
//!
//! A message is `u16 msg_size (LE), u8 msg_type, payload[msg_size]`. A header is taken
//! as corrupt, as pyulog takes it, when its type is 0 or its size is 0 or above 10,000
//! bytes; the reader then skips one byte at a time until a plausible header (a known
//! type, and for a data message a known subscription of a fitting size) follows.

use std::collections::HashMap;

use super::{looks_like, UlogReader};

/// The file header: magic (7 bytes), version (1), start time in µs (8).
pub(super) const HEADER_BYTES: usize = 16;
/// `u16 msg_size, u8 msg_type`.
const MESSAGE_HEADER_BYTES: usize = 3;
/// pyulog's `_check_packet_corruption`: larger messages are taken as corrupt.
const MAX_PLAUSIBLE_MESSAGE_BYTES: usize = 10_000;
/// Nested formats deeper than this are refused (a cycle in a corrupt file).
const MAX_NESTING: usize = 8;
/// The message types of the ULog specification.
const KNOWN_TYPES: &[u8] = b"BFIMPQARDLCSO";

/// A field's base type as a format definition names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum BaseType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
    Bool,
    Char,
}

impl BaseType {
    fn parse(name: &str) -> Option<BaseType> {
        Some(match name {
            "int8_t" => BaseType::I8,
            "uint8_t" => BaseType::U8,
            "int16_t" => BaseType::I16,
            "uint16_t" => BaseType::U16,
            "int32_t" => BaseType::I32,
            "uint32_t" => BaseType::U32,
            "int64_t" => BaseType::I64,
            "uint64_t" => BaseType::U64,
            "float" => BaseType::F32,
            "double" => BaseType::F64,
            "bool" => BaseType::Bool,
            "char" => BaseType::Char,
            _ => return None,
        })
    }

    pub(super) fn size(self) -> usize {
        match self {
            BaseType::I8 | BaseType::U8 | BaseType::Bool | BaseType::Char => 1,
            BaseType::I16 | BaseType::U16 => 2,
            BaseType::I32 | BaseType::U32 | BaseType::F32 => 4,
            BaseType::I64 | BaseType::U64 | BaseType::F64 => 8,
        }
    }
}

/// One field of a format definition: `type name` or `type[n] name`.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct FormatField {
    pub type_name: String,
    pub array_len: usize,
    pub name: String,
}

/// A format definition (`F` message): `name:type field;type field;...`.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Format {
    pub fields: Vec<FormatField>,
}

/// Where a base-type field of a subscribed topic lies in its data message's struct.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FieldAt {
    pub offset: usize,
    pub base: BaseType,
    pub array_len: usize,
}

impl FieldAt {
    /// Element `idx` as f64, or `None` past the struct's end or the array's.
    pub(super) fn read(&self, data: &[u8], idx: usize) -> Option<f64> {
        if idx >= self.array_len {
            return None;
        }
        let start = self.offset.checked_add(idx * self.base.size())?;
        let bytes = data.get(start..start.checked_add(self.base.size())?)?;
        let mut buffer = [0u8; 8];
        buffer[..bytes.len()].copy_from_slice(bytes);
        Some(match self.base {
            BaseType::I8 => bytes[0] as i8 as f64,
            BaseType::U8 | BaseType::Bool | BaseType::Char => bytes[0] as f64,
            BaseType::I16 => i16::from_le_bytes([buffer[0], buffer[1]]) as f64,
            BaseType::U16 => u16::from_le_bytes([buffer[0], buffer[1]]) as f64,
            BaseType::I32 => {
                i32::from_le_bytes([buffer[0], buffer[1], buffer[2], buffer[3]]) as f64
            }
            BaseType::U32 => {
                u32::from_le_bytes([buffer[0], buffer[1], buffer[2], buffer[3]]) as f64
            }
            BaseType::F32 => {
                f32::from_le_bytes([buffer[0], buffer[1], buffer[2], buffer[3]]) as f64
            }
            BaseType::I64 => i64::from_le_bytes(buffer) as f64,
            BaseType::U64 => u64::from_le_bytes(buffer) as f64,
            BaseType::F64 => f64::from_le_bytes(buffer),
        })
    }

    /// An unsigned 64-bit element exactly (timestamps in µs).
    pub(super) fn read_u64(&self, data: &[u8]) -> Option<u64> {
        let bytes = data.get(self.offset..self.offset.checked_add(8)?)?;
        match self.base {
            BaseType::U64 | BaseType::I64 => Some(u64::from_le_bytes(bytes.try_into().ok()?)),
            _ => self.read(data, 0).map(|value| value as u64),
        }
    }
}

/// Parses a format definition's text into its name and fields.
pub(super) fn parse_format(text: &str) -> Option<(String, Format)> {
    let (name, body) = text.split_once(':')?;
    let mut fields = Vec::new();
    for field in body
        .split(';')
        .map(str::trim)
        .filter(|field| !field.is_empty())
    {
        let (type_text, field_name) = field.rsplit_once(' ')?;
        let (type_name, array_len) = match type_text.split_once('[') {
            Some((base, len)) => (base, len.strip_suffix(']')?.parse::<usize>().ok()?),
            None => (type_text, 1),
        };
        fields.push(FormatField {
            type_name: type_name.trim().to_string(),
            array_len,
            name: field_name.to_string(),
        });
    }
    Some((name.trim().to_string(), Format { fields }))
}

/// The size of one element of `type_name` (a base type or a nested format), bytes.
fn type_size(formats: &HashMap<String, Format>, type_name: &str, depth: usize) -> Option<usize> {
    if let Some(base) = BaseType::parse(type_name) {
        return Some(base.size());
    }
    if depth >= MAX_NESTING {
        return None;
    }
    let format = formats.get(type_name)?;
    format.fields.iter().try_fold(0usize, |total, field| {
        let size = type_size(formats, &field.type_name, depth + 1)?;
        total.checked_add(size.checked_mul(field.array_len)?)
    })
}

/// A topic's struct laid out: the offsets of its top-level base-type fields, and its
/// size with and without the trailing padding the logger leaves out (pyulog: a data
/// message may be anywhere between the two).
#[derive(Debug, Clone, Default)]
pub(super) struct Layout {
    pub fields: HashMap<String, FieldAt>,
    pub min_bytes: usize,
    pub max_bytes: usize,
}

pub(super) fn layout(formats: &HashMap<String, Format>, format_name: &str) -> Option<Layout> {
    let format = formats.get(format_name)?;
    let mut layout = Layout::default();
    let mut offset = 0usize;
    for field in &format.fields {
        let size = type_size(formats, &field.type_name, 1)?.checked_mul(field.array_len)?;
        if let Some(base) = BaseType::parse(&field.type_name) {
            if !field.name.starts_with("_padding") {
                layout.fields.insert(
                    field.name.clone(),
                    FieldAt {
                        offset,
                        base,
                        array_len: field.array_len,
                    },
                );
            }
        }
        offset = offset.checked_add(size)?;
        if !field.name.starts_with("_padding") {
            layout.min_bytes = offset;
        }
    }
    layout.max_bytes = offset;
    Some(layout)
}

fn u16_at(bytes: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes([*bytes.get(at)?, *bytes.get(at + 1)?]))
}

impl UlogReader {
    /// How many bytes `pending` must hold before [`UlogReader::process`] can decide on
    /// its first message.
    pub(super) fn bytes_needed(&self, pending: &[u8]) -> usize {
        if !self.header_read {
            return HEADER_BYTES;
        }
        match (u16_at(pending, 0), pending.get(2)) {
            (Some(size), Some(&msg_type)) if msg_type == b'D' && pending.len() < 5 => {
                5.min(MESSAGE_HEADER_BYTES + size as usize)
            }
            (Some(size), Some(_)) => MESSAGE_HEADER_BYTES + size as usize,
            _ => MESSAGE_HEADER_BYTES,
        }
    }

    /// Frames and handles the complete messages at the start of `data` (which starts at
    /// file offset `self.offset`); returns how many bytes were used. What is left is an
    /// unfinished message. Every decision depends only on bytes already seen, so the
    /// chunking does not change the result.
    pub(super) fn process(&mut self, data: &[u8]) -> usize {
        let mut pos = 0usize;
        if self.stopped.is_some() {
            self.offset += data.len() as u64;
            return data.len();
        }
        if !self.header_read {
            if data.len() < HEADER_BYTES {
                return 0;
            }
            if !looks_like(data) {
                self.stopped = Some("byte 0: no ULog header (magic ULog 01 12 35)".into());
                self.offset += data.len() as u64;
                return data.len();
            }
            self.header_read = true;
            pos = HEADER_BYTES;
        }
        loop {
            if self.stopped.is_some() {
                pos = data.len();
                break;
            }
            let at = self.offset + pos as u64;
            if self.skip_until > at {
                let skip = (self.skip_until - at).min((data.len() - pos) as u64) as usize;
                pos += skip;
                if pos >= data.len() {
                    break;
                }
                continue;
            }
            let rest = &data[pos..];
            let (Some(size), Some(&msg_type)) = (u16_at(rest, 0), rest.get(2)) else {
                break;
            };
            let size = size as usize;
            let total = MESSAGE_HEADER_BYTES + size;
            if let Some(&appended_at) = self.appended_offsets.first() {
                if at >= appended_at {
                    self.appended_offsets.remove(0);
                } else if at + total as u64 > appended_at {
                    // pyulog reads up to the appended data's offset and goes on there.
                    self.appended_offsets.remove(0);
                    self.skip_until = appended_at;
                    continue;
                }
            }
            let lookahead = if msg_type == b'D' && size >= 2 { 5 } else { 3 };
            if rest.len() < lookahead {
                break;
            }
            let strict = self.resyncing_from.is_some();
            if !self.plausible(msg_type, size, u16_at(rest, 3), strict) {
                if self.resyncing_from.is_none() {
                    self.resyncing_from = Some(at);
                }
                pos += 1;
                self.n_bytes_skipped += 1;
                continue;
            }
            if rest.len() < total {
                break;
            }
            if let Some(from) = self.resyncing_from.take() {
                self.diagnostics.push(
                    None,
                    format!(
                        "byte {from}: corrupt message header; skipped {} bytes to the next \
                         plausible message at byte {at}",
                        at - from
                    ),
                );
            }
            self.handle(msg_type, &rest[MESSAGE_HEADER_BYTES..total], at);
            self.n_messages += 1;
            pos += total;
        }
        self.offset += pos as u64;
        pos
    }

    /// Whether a message header can be taken as it is. `strict` while resynchronising:
    /// then only the specification's types, and data only for a known subscription of
    /// a fitting size.
    fn plausible(&self, msg_type: u8, size: usize, msg_id: Option<u16>, strict: bool) -> bool {
        if msg_type == 0 || size == 0 || size > MAX_PLAUSIBLE_MESSAGE_BYTES {
            return false;
        }
        if !strict {
            return true;
        }
        if !KNOWN_TYPES.contains(&msg_type) {
            return false;
        }
        match msg_type {
            b'D' => msg_id
                .and_then(|msg_id| self.subscriptions.get(&msg_id))
                .is_some_and(|sub| {
                    size >= 2 + sub.layout.min_bytes && size <= 2 + sub.layout.max_bytes
                }),
            b'S' => size == 8,
            b'O' => size == 2,
            b'B' => false,
            _ => true,
        }
    }

    fn handle(&mut self, msg_type: u8, payload: &[u8], at: u64) {
        match msg_type {
            b'B' => self.flag_bits(payload, at),
            b'F' => {
                let text = String::from_utf8_lossy(payload);
                match parse_format(&text) {
                    Some((name, format)) => {
                        self.formats.insert(name, format);
                    }
                    None => self.diagnostics.push(
                        None,
                        format!("byte {at}: format definition not understood, skipped"),
                    ),
                }
            }
            b'I' => {
                if let Some((key, value)) = key_value(payload) {
                    let name = key.rsplit(' ').next().unwrap_or_default();
                    if name == "ver_sw_release" {
                        // 0xAABBCCTT: major, minor, patch, type (ULog spec, info keys).
                        self.ver_sw_release = value
                            .get(..4)
                            .and_then(|bytes| bytes.try_into().ok())
                            .map(u32::from_le_bytes);
                    }
                    if matches!(name, "sys_name" | "ver_hw" | "ver_sw") {
                        let text = String::from_utf8_lossy(value);
                        let text = text.trim_end_matches('\0').to_string();
                        self.info.push((name.to_string(), text));
                    }
                }
            }
            b'P' => self.parameter(payload, at),
            b'A' => self.subscribe(payload, at),
            b'R' => {
                if let Some(msg_id) = u16_at(payload, 0) {
                    self.subscriptions.remove(&msg_id);
                }
            }
            b'D' => {
                self.n_data_messages += 1;
                self.seen_data = true;
                self.data(payload, at);
            }
            b'O' => {
                self.n_dropouts += 1;
                self.dropout_ms += u64::from(u16_at(payload, 0).unwrap_or(0));
            }
            // Multi info, default parameters, logged strings, sync, new types: not used.
            _ => {}
        }
    }

    /// Flag bits (`B`): compat flags (8 bytes), incompat flags (8), three u64 offsets
    /// of appended data. Like pyulog, a log with an unknown incompatible bit is refused.
    fn flag_bits(&mut self, payload: &[u8], at: u64) {
        if self.n_messages > 0 {
            self.diagnostics.push(
                None,
                format!("byte {at}: flag bits after the first message, ignored"),
            );
            return;
        }
        let Some(incompat) = payload.get(8..16) else {
            self.diagnostics.push(
                None,
                format!("byte {at}: flag bits message too short, ignored"),
            );
            return;
        };
        if incompat[0] & !1 != 0 || incompat[1..].iter().any(|&byte| byte != 0) {
            self.stopped = Some(format!(
                "byte {at}: the log sets an incompatible flag this reader does not know \
                 (pyulog refuses such logs too)"
            ));
            return;
        }
        if incompat[0] & 1 != 0 {
            for idx in 0..3 {
                let Some(bytes) = payload.get(16 + 8 * idx..24 + 8 * idx) else {
                    break;
                };
                let mut buffer = [0u8; 8];
                buffer.copy_from_slice(bytes);
                let offset = u64::from_le_bytes(buffer);
                if offset == 0 {
                    continue;
                }
                if offset <= at {
                    self.diagnostics.push(
                        None,
                        format!("byte {at}: appended data offset {offset} lies before it, ignored"),
                    );
                    continue;
                }
                self.appended_offsets.push(offset);
            }
            self.appended_offsets.sort_unstable();
        }
    }

    /// A parameter (`P`): `int32_t NAME` or `float NAME`, then the 4-byte value.
    fn parameter(&mut self, payload: &[u8], at: u64) {
        let value = key_value(payload).and_then(|(key, value)| {
            let (type_name, name) = key.split_once(' ')?;
            let bytes: [u8; 4] = value.get(..4)?.try_into().ok()?;
            let value = match type_name {
                "int32_t" => i32::from_le_bytes(bytes) as f64,
                "float" => f32::from_le_bytes(bytes) as f64,
                _ => return None,
            };
            Some((name.to_string(), value))
        });
        let Some((name, value)) = value else {
            self.diagnostics.push(
                None,
                format!("byte {at}: parameter not understood, skipped"),
            );
            return;
        };
        match self.param_idx.get(&name) {
            Some(&idx) if !self.seen_data => {
                if let Some(entry) = self.params.get_mut(idx) {
                    entry.1 = value;
                }
            }
            Some(&idx) => {
                let in_force = self.params.get(idx).map(|entry| entry.1);
                match self.params_changed.iter_mut().find(|entry| entry.0 == name) {
                    Some(entry) => entry.1 = value,
                    None if in_force != Some(value) => self.params_changed.push((name, value)),
                    None => {}
                }
            }
            None if !self.seen_data => {
                self.param_idx.insert(name.clone(), self.params.len());
                self.params.push((name, value));
            }
            None => match self.params_changed.iter_mut().find(|entry| entry.0 == name) {
                Some(entry) => entry.1 = value,
                None => self.params_changed.push((name, value)),
            },
        }
    }
}

/// An info or parameter message: `u8 key_len, key, value`.
fn key_value(payload: &[u8]) -> Option<(String, &[u8])> {
    let key_len = *payload.first()? as usize;
    let key = payload.get(1..1 + key_len)?;
    let value = payload.get(1 + key_len..)?;
    Some((String::from_utf8_lossy(key).into_owned(), value))
}
