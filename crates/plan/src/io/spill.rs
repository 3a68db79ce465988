//! Tile files for the streaming mode ([`crate::streaming`]): points appended to one temporary
//! file per spatial tile, in the order they arrive, and read back a tile at a time.
//!
//! A record is the point's local x, y, z as little-endian `f32`, then its scan slot (`u16`)
//! and time (`f64`) when the store keeps them. The folder is removed when the store is dropped.

use std::fs::File;
use std::io::{Read, Write};
use std::path::Path;

/// Why a tile file could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum SpillError {
    #[error("tile files in {dir}: {source}")]
    Io { dir: String, source: std::io::Error },
    #[error("tile file {tile} is corrupt: {why}")]
    Corrupt { tile: usize, why: String },
}

/// The points of one tile, as read back.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct TilePoints {
    pub xyz: Vec<[f32; 3]>,
    /// Empty when the store keeps no scan slots.
    pub scan: Vec<u16>,
    /// Empty when the store keeps no times.
    pub time: Vec<f64>,
}

/// One temporary file per tile, each with a write buffer of its own.
pub struct TileStore {
    dir: tempfile::TempDir,
    files: Vec<File>,
    buffers: Vec<Vec<u8>>,
    counts: Vec<u64>,
    buffer: usize,
    has_scan: bool,
    has_time: bool,
}

impl TileStore {
    /// Creates `tiles` empty tile files in a new folder inside `parent` (the system's temporary
    /// folder when `None`), each buffered by `buffer` bytes.
    pub fn create(
        tiles: usize,
        parent: Option<&Path>,
        buffer: usize,
        has_scan: bool,
        has_time: bool,
    ) -> Result<TileStore, SpillError> {
        let parent = parent.map_or_else(std::env::temp_dir, Path::to_path_buf);
        let dir = tempfile::Builder::new()
            .prefix("asbuilt-tiles-")
            .tempdir_in(&parent)
            .map_err(|source| SpillError::Io {
                dir: parent.display().to_string(),
                source,
            })?;
        let mut store = TileStore {
            files: Vec::with_capacity(tiles),
            buffers: Vec::with_capacity(tiles),
            counts: vec![0; tiles],
            buffer: buffer.max(4096),
            has_scan,
            has_time,
            dir,
        };
        for t in 0..tiles {
            let path = store.dir.path().join(format!("tile-{t}.bin"));
            let file = File::options()
                .create_new(true)
                .read(true)
                .write(true)
                .open(&path)
                .map_err(|e| store.io(e))?;
            store.files.push(file);
            store.buffers.push(Vec::new());
        }
        Ok(store)
    }

    fn io(&self, source: std::io::Error) -> SpillError {
        SpillError::Io {
            dir: self.dir.path().display().to_string(),
            source,
        }
    }

    /// Bytes per record.
    pub fn record_len(&self) -> usize {
        12 + 2 * usize::from(self.has_scan) + 8 * usize::from(self.has_time)
    }

    /// Appends a point to `tile`. `scan` and `time` are written when the store keeps them.
    #[inline]
    pub fn push(
        &mut self,
        tile: usize,
        p: [f32; 3],
        scan: u16,
        time: f64,
    ) -> Result<(), SpillError> {
        let buf = &mut self.buffers[tile];
        for c in p {
            buf.extend_from_slice(&c.to_le_bytes());
        }
        if self.has_scan {
            buf.extend_from_slice(&scan.to_le_bytes());
        }
        if self.has_time {
            buf.extend_from_slice(&time.to_le_bytes());
        }
        self.counts[tile] += 1;
        if buf.len() >= self.buffer {
            self.flush_tile(tile)?;
        }
        Ok(())
    }

    fn flush_tile(&mut self, tile: usize) -> Result<(), SpillError> {
        let mut buf = std::mem::take(&mut self.buffers[tile]);
        let result = self.files[tile].write_all(&buf);
        buf.clear();
        self.buffers[tile] = buf;
        result.map_err(|e| self.io(e))
    }

    /// Writes out every buffer and frees them; call once all points are in.
    pub fn flush(&mut self) -> Result<(), SpillError> {
        for t in 0..self.files.len() {
            self.flush_tile(t)?;
            self.buffers[t] = Vec::new();
        }
        Ok(())
    }

    /// Points written to `tile` (the tests check the files against it).
    #[cfg(test)]
    pub fn count(&self, tile: usize) -> u64 {
        self.counts[tile]
    }

    /// Bytes in all tile files.
    pub fn bytes(&self) -> u64 {
        self.counts.iter().sum::<u64>() * self.record_len() as u64
    }

    /// Reads `tile` back in the order its points were pushed, decoding in bounded blocks so
    /// the raw bytes are never held whole.
    pub fn read(&self, tile: usize) -> Result<TilePoints, SpillError> {
        let n = self.counts[tile] as usize;
        let rec = self.record_len();
        let mut out = TilePoints {
            xyz: Vec::with_capacity(n),
            scan: Vec::with_capacity(if self.has_scan { n } else { 0 }),
            time: Vec::with_capacity(if self.has_time { n } else { 0 }),
        };
        let mut file = &self.files[tile];
        std::io::Seek::seek(&mut file, std::io::SeekFrom::Start(0)).map_err(|e| self.io(e))?;
        let per_block = (1 << 20) / rec;
        let mut block = vec![0u8; per_block * rec];
        let mut left = n;
        while left > 0 {
            let k = left.min(per_block);
            let bytes = &mut block[..k * rec];
            file.read_exact(bytes).map_err(|e| match e.kind() {
                std::io::ErrorKind::UnexpectedEof => SpillError::Corrupt {
                    tile,
                    why: format!("it ends before its {n} points"),
                },
                _ => self.io(e),
            })?;
            for r in bytes.chunks_exact(rec) {
                let f = |o: usize| f32::from_le_bytes([r[o], r[o + 1], r[o + 2], r[o + 3]]);
                out.xyz.push([f(0), f(4), f(8)]);
                let mut o = 12;
                if self.has_scan {
                    out.scan.push(u16::from_le_bytes([r[o], r[o + 1]]));
                    o += 2;
                }
                if self.has_time {
                    let mut t = [0u8; 8];
                    t.copy_from_slice(&r[o..o + 8]);
                    out.time.push(f64::from_le_bytes(t));
                }
            }
            left -= k;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_come_back_per_tile_in_order() {
        let mut store = TileStore::create(3, None, 4096, true, true).unwrap();
        for k in 0..10_000u32 {
            let p = [k as f32, -(k as f32), 0.5];
            store
                .push(k as usize % 3, p, (k % 7) as u16, f64::from(k))
                .unwrap();
        }
        store.flush().unwrap();
        assert_eq!(store.record_len(), 22);
        assert_eq!(store.bytes(), 10_000 * 22);
        let t1 = store.read(1).unwrap();
        assert_eq!(t1.xyz.len() as u64, store.count(1));
        assert_eq!(t1.xyz[0], [1.0, -1.0, 0.5]);
        assert_eq!(t1.xyz[1], [4.0, -4.0, 0.5]);
        assert_eq!(t1.scan[1], 4);
        assert_eq!(*t1.time.last().unwrap(), 9997.0);
        // Reading twice gives the same points.
        assert_eq!(store.read(1).unwrap(), t1);
        let bare = TileStore::create(1, None, 4096, false, false).unwrap();
        assert_eq!(bare.record_len(), 12);
        assert!(bare.read(0).unwrap().xyz.is_empty());
    }
}
