//! Flash storage of the constellation and the calibration, so they survive a reset.
//!
//! Two flash pages are used alternately (A/B): a save writes the *other* page with a
//! generation number one higher, so a reset or power loss in the middle of a write leaves
//! the previous record intact. A page holds one record:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `b"CTAS"` |
//! | 4 | 2 | record format version ([`FORMAT_VERSION`]) |
//! | 6 | 2 | payload length `n` (bytes) |
//! | 8 | 4 | generation (higher is newer) |
//! | 12 | n | payload: postcard encoding of the stored value |
//! | 12+n | 4 | CRC-32C (the wire protocol's) over bytes 0 .. 12+n |
//!
//! The whole record is padded to an even length (the STM32F1 programs half-words).
//! Loading picks the valid record with the highest generation; a record with a wrong
//! magic, version, length or CRC, or whose payload does not decode, is ignored.
//!
//! The module is generic over [`FlashPages`], implemented by the chip's flash writer in
//! `main.rs` and by [`RamFlash`] on the host.

use serde::{de::DeserializeOwned, Serialize};

/// Record format version; bump when the stored types change. 5 (protocol 7): the
/// calibration's magnitude law and each beacon's brightness.
pub const FORMAT_VERSION: u16 = 5;
/// Largest record (header + payload + CRC), bytes. Fits one 1 KiB page of the F103x8.
pub const MAX_RECORD: usize = 512;
const HEADER: usize = 12;
const MAGIC: [u8; 4] = *b"CTAS";

/// Flash failure (from the device), or a value too large to store.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StorageError {
    /// Erase failed.
    Erase,
    /// Programming or verification failed.
    Write,
    /// The value does not fit in [`MAX_RECORD`].
    TooLarge,
}

/// Two erasable pages of non-volatile memory.
pub trait FlashPages {
    /// The current contents of page `page` (0 or 1), at least [`MAX_RECORD`] bytes.
    fn read(&self, page: usize) -> &[u8];
    /// Erase page `page` (to `0xFF`).
    fn erase(&mut self, page: usize) -> Result<(), StorageError>;
    /// Program `data` (even length) at the start of page `page`.
    fn write(&mut self, page: usize, data: &[u8]) -> Result<(), StorageError>;
}

/// A decoded record: its generation and value.
fn decode<T: DeserializeOwned>(bytes: &[u8]) -> Option<(u32, T)> {
    if bytes.len() < HEADER + 4 || bytes[..4] != MAGIC {
        return None;
    }
    let version = u16::from_le_bytes([bytes[4], bytes[5]]);
    let n = u16::from_le_bytes([bytes[6], bytes[7]]) as usize;
    if version != FORMAT_VERSION || HEADER + n + 4 > bytes.len().min(MAX_RECORD) {
        return None;
    }
    let generation = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
    let crc = &bytes[HEADER + n..HEADER + n + 4];
    if cta_core::wire::crc32c(&bytes[..HEADER + n]).to_le_bytes() != crc {
        return None;
    }
    let value = postcard::from_bytes(&bytes[HEADER..HEADER + n]).ok()?;
    Some((generation, value))
}

/// The stored value with the highest generation, and that generation; `None` if neither
/// page holds a valid record (first boot, or a format change).
pub fn load<T: DeserializeOwned, F: FlashPages>(flash: &F) -> Option<(u32, T)> {
    let a = decode::<T>(flash.read(0));
    let b = decode::<T>(flash.read(1));
    match (a, b) {
        (Some(a), Some(b)) => Some(if b.0 > a.0 { b } else { a }),
        (a, b) => a.or(b),
    }
}

/// Store `value` in the page not holding the newest record. Returns the new generation.
pub fn save<T: Serialize, F: FlashPages>(flash: &mut F, value: &T) -> Result<u32, StorageError> {
    let newest = [0, 1].map(|p| newest_generation(flash.read(p)));
    let (page, generation) = match newest {
        [Some(a), Some(b)] if a >= b => (1, a.wrapping_add(1)),
        [Some(_), Some(b)] => (0, b.wrapping_add(1)),
        [Some(a), None] => (1, a.wrapping_add(1)),
        [None, Some(b)] => (0, b.wrapping_add(1)),
        [None, None] => (0, 1),
    };
    let mut rec = [0xFFu8; MAX_RECORD];
    let n = postcard::to_slice(value, &mut rec[HEADER..MAX_RECORD - 4])
        .map_err(|_| StorageError::TooLarge)?
        .len();
    rec[..4].copy_from_slice(&MAGIC);
    rec[4..6].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    rec[6..8].copy_from_slice(&(n as u16).to_le_bytes());
    rec[8..12].copy_from_slice(&generation.to_le_bytes());
    let crc = cta_core::wire::crc32c(&rec[..HEADER + n]);
    rec[HEADER + n..HEADER + n + 4].copy_from_slice(&crc.to_le_bytes());
    let len = (HEADER + n + 4 + 1) & !1;
    flash.erase(page)?;
    flash.write(page, &rec[..len])?;
    Ok(generation)
}

/// Generation of a page's record if its header and CRC are intact (payload not decoded).
fn newest_generation(bytes: &[u8]) -> Option<u32> {
    decode::<postcard_raw::Any>(bytes).map(|(g, _)| g)
}

mod postcard_raw {
    //! A payload type that accepts any postcard bytes (used to read a record's
    //! generation without knowing the stored type).
    use serde::de::{Deserialize, Deserializer};

    pub struct Any;

    impl<'de> Deserialize<'de> for Any {
        fn deserialize<D: Deserializer<'de>>(_: D) -> Result<Self, D::Error> {
            Ok(Any)
        }
    }
}

/// Two pages of RAM standing in for flash (host tests and the simulated board).
#[derive(Debug, Clone)]
pub struct RamFlash {
    /// Page contents.
    pub pages: [[u8; MAX_RECORD]; 2],
    /// When set, the next write stops after this many bytes (simulates a reset mid-write).
    pub fail_after: Option<usize>,
}

impl Default for RamFlash {
    fn default() -> Self {
        Self {
            pages: [[0xFF; MAX_RECORD]; 2],
            fail_after: None,
        }
    }
}

impl FlashPages for RamFlash {
    fn read(&self, page: usize) -> &[u8] {
        &self.pages[page & 1]
    }
    fn erase(&mut self, page: usize) -> Result<(), StorageError> {
        self.pages[page & 1] = [0xFF; MAX_RECORD];
        Ok(())
    }
    fn write(&mut self, page: usize, data: &[u8]) -> Result<(), StorageError> {
        let n = match self.fail_after.take() {
            Some(k) => k.min(data.len()),
            None => data.len(),
        };
        self.pages[page & 1][..n].copy_from_slice(&data[..n]);
        if n < data.len() {
            return Err(StorageError::Write);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
    struct Cfg {
        a: [f32; 3],
        n: u8,
    }

    #[test]
    fn empty_flash_loads_nothing() {
        assert_eq!(load::<Cfg, _>(&RamFlash::default()), None);
    }

    #[test]
    fn newest_wins_and_torn_write_keeps_previous() {
        let mut f = RamFlash::default();
        let c1 = Cfg {
            a: [1.0, 2.0, 3.0],
            n: 1,
        };
        let c2 = Cfg {
            a: [4.0, 5.0, 6.0],
            n: 2,
        };
        let c3 = Cfg {
            a: [7.0, 8.0, 9.0],
            n: 3,
        };
        assert_eq!(save(&mut f, &c1), Ok(1));
        assert_eq!(save(&mut f, &c2), Ok(2));
        assert_eq!(load::<Cfg, _>(&f), Some((2, c2)));
        f.fail_after = Some(10);
        assert_eq!(save(&mut f, &c3), Err(StorageError::Write));
        let (g, v) = load::<Cfg, _>(&f).unwrap();
        assert_eq!((g, v.n), (2, 2));
        assert_eq!(save(&mut f, &c3), Ok(3));
        assert_eq!(load::<Cfg, _>(&f).unwrap().1, c3);
    }

    #[test]
    fn corrupted_bits_are_rejected() {
        let mut f = RamFlash::default();
        save(&mut f, &Cfg { a: [1.0; 3], n: 9 }).unwrap();
        // 12 header + 13 payload + 4 CRC bytes (byte 29 is padding).
        for i in 0..29 {
            let mut g = f.clone();
            g.pages[0][i] ^= 0x08;
            assert_eq!(load::<Cfg, _>(&g), None, "flipped byte {i}");
        }
    }
}
