//! LAS and LAZ read a batch at a time ([`crate::io::chunks`]), with the whole-file reader's
//! header checks, bounds guard and point builder, so the points are exactly those
//! [`super::read_las`] reads.

use std::io::{Read, Seek};

use las::{PointData, PointDataBuilder, Reader};

use super::{check_header, crs_of, describe, open_reader, BoundsGuard, CHUNK};
use crate::cloud::PointCloud;
use crate::io::assemble::CloudBuilder;
use crate::io::chunks::{hand_over, PointChunk, PointChunks};
use crate::io::{ReadError, ReadOptions};

/// A LAS or LAZ source being read in batches.
pub struct LasChunks {
    reader: Reader,
    header: las::Header,
    builder: CloudBuilder,
    guard: BoundsGuard,
    pd: PointData,
    name: String,
    format: &'static str,
    count: u64,
    done: u64,
}

impl LasChunks {
    /// Checks the header of the `len`-byte source and readies the decoder.
    pub fn open<R>(
        mut source: R,
        len: u64,
        name: &str,
        options: &ReadOptions,
    ) -> Result<LasChunks, ReadError>
    where
        R: Read + Seek + Send + Sync + 'static,
    {
        let plan = check_header(&mut source, len, name)?;
        let format = plan.format;
        // Batches are decoded one at a time, a few ahead of the caller: sequentially.
        let reader = open_reader(source, &plan, false)
            .map_err(|e| ReadError::named(name, format, e.to_string()))?;
        let header = reader.header().clone();
        let pd = PointDataBuilder::new().for_header(&header).build();
        Ok(LasChunks {
            builder: CloudBuilder::new(format, 0, None, options.keep_time),
            guard: BoundsGuard::new(&header),
            count: header.number_of_points(),
            header,
            reader,
            pd,
            name: name.to_string(),
            format,
            done: 0,
        })
    }
}

impl PointChunks for LasChunks {
    fn next_chunk(&mut self, chunk: &mut PointChunk) -> Result<bool, ReadError> {
        let (name, fname, count, done) = (self.name.as_str(), self.format, self.count, self.done);
        let n = self.reader.fill_points(CHUNK, &mut self.pd).map_err(|e| {
            ReadError::at(
                name,
                fname,
                e.to_string(),
                format!("point {done} of {count}"),
            )
        })?;
        if n == 0 {
            if done < count {
                return Err(ReadError::at(
                    name,
                    fname,
                    format!("the header claims {count} points but the data ends after {done}"),
                    format!("point {done}"),
                ));
            }
            hand_over(chunk, &mut Vec::new(), &mut Vec::new(), &mut Vec::new());
            return Ok(false);
        }
        let pd = &self.pd;
        let mut times = pd.gps_time();
        for (i, (((x, y), z), id)) in pd
            .x()
            .zip(pd.y())
            .zip(pd.z())
            .zip(pd.point_source_id())
            .enumerate()
        {
            let p = [x, y, z];
            if !self.guard.contains(p) {
                return Err(ReadError::at(
                    name,
                    fname,
                    format!(
                        "({x}, {y}, {z}) lies outside the header's bounding box; the point data is corrupt{}",
                        if fname == "laz" { " (a damaged compressed chunk?)" } else { "" }
                    ),
                    format!("point {}", done + i as u64),
                ));
            }
            let slot = self
                .builder
                .scan_slot(u32::from(id))
                .map_err(|why| ReadError::named(name, fname, why))?;
            let t = times.as_mut().and_then(|t| t.next());
            self.builder.push(p, Some(slot), t);
        }
        self.done += n;
        let c = self.builder.cloud_mut();
        hand_over(chunk, &mut c.xyz, &mut c.scan, &mut c.time);
        Ok(true)
    }

    fn skeleton(&self) -> Result<PointCloud, ReadError> {
        let crs = crs_of(&self.header);
        let details = describe(&self.header, crs.as_ref().map(|c| c.1));
        let mut cloud = self.builder.skeleton(details);
        cloud.crs = crs.map(|c| c.0);
        Ok(cloud)
    }
}
