//! The file under the fixed-size record readers (binary PLY, uncompressed LAS), read through a
//! read-only memory map.
//!
//! A mapped file is decoded a block at a time straight from the page cache, with no copy into a
//! buffer. Each block's pages leave the process once it is decoded, so a mapped read holds no
//! more of the file than a buffered one, and the kernel is asked to read the next block ahead
//! meanwhile. Sources that are not files are read through `pool::read_ahead` instead.
//!
//! Huge pages for the cloud's arrays were tried and left out: on this project's virtual
//! machines a fresh 2 MiB page is sometimes far slower to fault in than 512 small ones (the
//! host backs it anew), so the read was faster at best and several times slower at worst.
//!
//! The allocator is told here, too, how much freed memory to keep (see [`keep_freed_memory`]).
//!
//! The crate's only `unsafe` code is here: the map, dropping a decoded block's pages, and that
//! one word to the allocator.
#![allow(unsafe_code)]

use std::fs::File;
use std::io;

use memmap2::{Advice, Mmap, UncheckedAdvice};

use super::{BytesRead, ReadOptions};
use crate::cancel::Cancel;

/// A whole file mapped read-only, with the read's stop token and progress counter.
pub(crate) struct Mapped {
    map: Mmap,
    cancel: Cancel,
    bytes: BytesRead,
}

impl Mapped {
    /// Maps `file`; `None` when it is not a non-empty regular file or the system will not map
    /// it (the caller then reads it as a stream).
    pub fn new(file: &File, options: &ReadOptions) -> Option<Mapped> {
        let meta = file.metadata().ok()?;
        if !meta.is_file() || meta.len() == 0 {
            return None;
        }
        // SAFETY: the map is read-only and only ever read as bytes, any value of which is
        // valid, and it is dropped with the read. What no map can guard against is another
        // process changing the file meanwhile: the decoders would see the new bytes, as `read`
        // would, and a truncation ends the process with SIGBUS at the first page past the new
        // end. Files are mapped only when named by path (the CLI's input, the service's stored
        // upload), which nothing rewrites while it is read.
        let map = unsafe { Mmap::map(file) }.ok()?;
        // The blocks are read front to back: the kernel may read further ahead.
        let _ = map.advise(Advice::Sequential);
        Some(Mapped {
            map,
            cancel: options.cancel.clone(),
            bytes: options.bytes.clone(),
        })
    }

    /// The file's length when it was mapped.
    pub fn len(&self) -> u64 {
        self.map.len() as u64
    }

    /// Hands `use_block` blocks `0..blocks` in order, as `pool::read_ahead` hands the blocks it
    /// reads: block `k` is the `len(k)` bytes after the blocks before it, the first from byte
    /// `start`. A block the file does not hold whole comes with the bytes there are and the
    /// error `read_exact` gives; once the read is stopped, a block comes empty with the error
    /// its source gives. No block follows a failed one.
    pub fn blocks<E>(
        &self,
        start: u64,
        blocks: usize,
        len: impl Fn(usize) -> usize,
        mut use_block: impl FnMut(usize, &[u8], io::Result<()>) -> Result<(), E>,
    ) -> Result<(), E> {
        let size = self.map.len();
        let mut at = usize::try_from(start).map_or(size, |s| s.min(size));
        let mut done = 0;
        for k in 0..blocks {
            let end = at.saturating_add(len(k));
            // Borrowed for this block only: its pages are dropped once it is decoded.
            let file: &[u8] = &self.map;
            let (block, filled) = match self.cancel.check() {
                Err(stop) => (&file[at..at], Err(io::Error::other(stop))),
                Ok(()) if end > size => (&file[at..], Err(short())),
                Ok(()) => (&file[at..end], Ok(())),
            };
            if filled.is_ok() && k + 1 < blocks && end < size {
                let next = len(k + 1).min(size - end);
                let _ = self.map.advise_range(Advice::WillNeed, end, next);
            }
            self.bytes.reached((at + block.len()) as u64);
            let failed = filled.is_err();
            use_block(k, block, filled)?;
            if failed {
                break;
            }
            self.release(done, end);
            done = end;
            at = end;
        }
        Ok(())
    }

    /// Drops the pages of bytes `from..to`, which are decoded, from the process (not from the
    /// page cache): they no longer count in its resident memory.
    fn release(&self, from: usize, to: usize) {
        if to > from {
            // SAFETY: nothing borrows these bytes any more, and the map is a read-only shared
            // one, so dropping its pages changes nothing a reader could see: a later read of
            // them would fault them in again from the file, unchanged.
            let _ = unsafe {
                self.map
                    .unchecked_advise_range(UncheckedAdvice::DontNeed, from, to - from)
            };
        }
    }
}

/// The error `read_exact` gives for a source that ends too soon.
fn short() -> io::Error {
    io::Error::new(io::ErrorKind::UnexpectedEof, "failed to fill whole buffer")
}

/// Freed blocks below this size are kept by the allocator for reuse; larger ones are mapped
/// afresh and go back to the kernel when freed (the cloud's arrays, the grids' copies).
const KEEP_BELOW: usize = 4 << 20;

/// Tells glibc's allocator to keep up to a few megabytes freed in each thread's heap, rather
/// than hand back the heap's top whenever 128 KiB of it lie free. A LAZ chunk's decoder
/// allocates about a megabyte and frees it at the chunk's end; given back each time, it was
/// faulted in anew for every chunk (58,000 extra faults in a 17 M-point read). glibc raises
/// these thresholds itself after the first large free, higher than this; the peak measured
/// lower. Called once, first thing in the process; other allocators are left alone.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only sets two of glibc's allocator parameters; it is called before any
    // other thread exists and takes no pointers. A refused setting leaves the default.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, KEEP_BELOW as libc::c_int);
        libc::mallopt(libc::M_TRIM_THRESHOLD, (2 * KEEP_BELOW) as libc::c_int);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Read, Seek, SeekFrom};

    fn map_of(bytes: &[u8], options: &ReadOptions) -> (tempfile::TempDir, Mapped) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        std::fs::write(&path, bytes).unwrap();
        let map = Mapped::new(&File::open(&path).unwrap(), options).expect("a file maps");
        (dir, map)
    }

    /// What a block handed over holds: its bytes, and the error's kind and text.
    type Seen = (Vec<u8>, Result<(), (io::ErrorKind, String)>);

    fn seen(buf: &[u8], filled: io::Result<()>) -> Seen {
        (buf.to_vec(), filled.map_err(|e| (e.kind(), e.to_string())))
    }

    #[test]
    fn blocks_are_what_read_exact_reads_up_to_the_same_error() {
        let bytes: Vec<u8> = (0..20_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let (_dir, map) = map_of(&bytes, &ReadOptions::default());
        assert_eq!(map.len(), 20_000);
        // Blocks across page ends; the fifth runs past the end, the sixth never comes.
        let lens = [3_000, 4_096, 2_500, 7_000, 4_000, 10];
        let mut from_map = Vec::new();
        map.blocks(
            100,
            lens.len(),
            |k| lens[k],
            |_, buf, filled| {
                from_map.push(seen(buf, filled));
                Ok::<(), ()>(())
            },
        )
        .unwrap();
        let mut stream = std::io::Cursor::new(&bytes);
        stream.seek(SeekFrom::Start(100)).unwrap();
        let mut from_stream = Vec::new();
        for len in lens {
            let at = stream.position() as usize;
            let mut buf = vec![0; len];
            let filled = stream.read_exact(&mut buf);
            let failed = filled.is_err();
            // A failed `read_exact` leaves its buffer unspecified: compare what the file held.
            let end = (at + len).min(bytes.len());
            from_stream.push(seen(&bytes[at..end], filled));
            if failed {
                break;
            }
        }
        assert_eq!(from_map.len(), 5);
        assert_eq!(from_map, from_stream);
    }

    #[test]
    fn a_stopped_read_gets_no_bytes_and_the_stop_as_its_error() {
        let cancel = Cancel::new();
        cancel.cancel();
        let options = ReadOptions {
            cancel,
            ..Default::default()
        };
        let (_dir, map) = map_of(&[1; 5_000], &options);
        let mut calls = Vec::new();
        map.blocks(
            0,
            3,
            |_| 1_000,
            |k, buf, filled| {
                calls.push((k, buf.len(), filled.unwrap_err().to_string()));
                Ok::<(), ()>(())
            },
        )
        .unwrap();
        assert_eq!(calls, vec![(0, 0, "cancelled".to_string())]);
    }
}
