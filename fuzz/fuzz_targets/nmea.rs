#![no_main]

use libfuzzer_sys::fuzz_target;

/// Rewrites every line that starts with '$' or '!' so that its checksum is valid:
/// anything from the line's last '*' on is dropped, then `*XX` is appended, XX the XOR
/// of the bytes after the leading '$'/'!' (two uppercase hex digits). Lines are split on
/// '\n' and joined with '\n' again; everything else is left as it is.
fn fix_checksums(data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() + data.len() / 8);
    for (index, line) in data.split(|&byte| byte == b'\n').enumerate() {
        if index > 0 {
            out.push(b'\n');
        }
        match line.first() {
            Some(b'$') | Some(b'!') => {
                let body = match line.iter().rposition(|&byte| byte == b'*') {
                    Some(star) => &line[..star],
                    None => line,
                };
                let checksum = body[1..].iter().fold(0u8, |acc, &byte| acc ^ byte);
                out.extend_from_slice(body);
                out.push(b'*');
                out.extend_from_slice(format!("{checksum:02X}").as_bytes());
            }
            _ => out.extend_from_slice(line),
        }
    }
    out
}

fuzz_target!(|data: &[u8]| {
    let fixed = fix_checksums(data);
    let _ = compass_pdr::io::nmea::read("fuzz.nmea", &fixed);
});
