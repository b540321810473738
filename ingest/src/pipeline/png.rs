//! The PNG writer: the coverage PNG, the structure images and the ground images streamed
//! band by band, and the sidecar, committed as one set ([`crate::output::write_set`]).

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::cloudmap::{
    extra_path, extra_writer, file_name, ground_writers, rgba16_writer, sidecar_json,
};
use crate::error::Result;
use crate::meta::{ExtraImage, ExtraRole};
use crate::output::{write_set, ExtraWriter};

use super::bands::stream_bands;
use super::pixels::StructureStats;
use super::stats::Stats;
use super::Plan;

/// Extra images to write: (path, streaming writer).
type ExtraSet<'a> = Vec<(PathBuf, ExtraWriter<'a>)>;

impl Plan {
    /// Stream the map to `png_path` and its sidecar (`.json`), computing bands in parallel,
    /// and commit them as one pair ([`crate::output::write_pair`]): on any error the previous
    /// pair (if any) is left as it was. Neither file may be the forecast file read.
    /// `progress` is called with the number of rows done.
    pub fn write(&self, png_path: &Path, progress: &(dyn Fn(usize) + Sync)) -> Result<PathBuf> {
        let stats = std::cell::RefCell::new(Stats::default());
        let structure_stats = std::cell::RefCell::new(StructureStats::new());
        let (mut extras, listed) = self.extra_writers(png_path)?;
        let ground = match &self.ground {
            Some(g) => {
                let (meta, writers) = ground_writers(png_path, g)?;
                extras.extend(writers);
                Some(meta)
            }
            None => None,
        };
        write_set(
            png_path,
            &[self.source.as_path()],
            |w, id| {
                let mut wr = rgba16_writer(w, self.width as u32, self.height as u32, id)?;
                let mut sw = wr.stream_writer().map_err(|e| e.to_string())?;
                let mut st = Stats::default();
                let mut sst = StructureStats::new();
                stream_bands(
                    self.height,
                    |a, b| self.band(a, b),
                    |(p, s)| {
                        st.add(&p);
                        sst.merge(&s);
                        let mut bytes = Vec::with_capacity(p.len() * 8);
                        for t in &p {
                            for c in t {
                                bytes.extend_from_slice(&c.to_be_bytes());
                            }
                        }
                        sw.write_all(&bytes).map_err(|e| e.to_string())
                    },
                    progress,
                )?;
                sw.finish().map_err(|e| e.to_string())?;
                *stats.borrow_mut() = st;
                *structure_stats.borrow_mut() = sst;
                Ok(())
            },
            extras,
            |name, id| {
                let mut meta = self.meta.clone();
                stats.borrow().apply(&mut meta);
                self.apply_structure(&mut meta, &structure_stats.borrow());
                meta.extra_images = listed;
                meta.structure_grid = Some(self.sampler.lattice());
                meta.ground = ground;
                sidecar_json(&meta, name, id, png_path)
            },
        )
    }

    /// The extra images of a map written to `png_path`: (path, streaming writer), and the
    /// sidecar's list of them.
    fn extra_writers<'a>(&'a self, png_path: &Path) -> Result<(ExtraSet<'a>, Vec<ExtraImage>)> {
        let mut writers: Vec<(PathBuf, ExtraWriter<'a>)> = Vec::new();
        let mut listed = Vec::new();
        let g = self.sampler.lattice();
        let (w, h) = (g.width as usize, g.height as usize);
        for role in ExtraRole::ALL {
            let path = extra_path(png_path, role);
            listed.push(ExtraImage {
                role,
                image: file_name(&path)?,
            });
            writers.push((
                path,
                Box::new(move |out, id| {
                    let mut wr = extra_writer(out, role, w as u32, h as u32, id)?;
                    let mut sw = wr.stream_writer().map_err(|e| e.to_string())?;
                    stream_bands(
                        h,
                        |a, b| {
                            let mut v = Vec::new();
                            for j in a..b {
                                self.sampler.append_row(role, j, &mut v);
                            }
                            v
                        },
                        |p| sw.write_all(&p).map_err(|e| e.to_string()),
                        |_| {},
                    )?;
                    sw.finish().map_err(|e| e.to_string())
                }),
            ));
        }
        Ok((writers, listed))
    }
}
