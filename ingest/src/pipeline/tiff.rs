//! The GeoTIFF writer: the coverage as one tiled, georeferenced GeoTIFF with overviews, the
//! sidecar's content in its GDAL metadata, and, when the forecast held more than RH, the
//! structure decoded to physical units as a second image ([`crate::geotiff`] does the format).

use std::path::Path;

use crate::error::{IngestError, Result};
use crate::geotiff::{GeoRef, GeoTiffSpec, GeoTiffWriter, PageBand, PageSpec};
use crate::layer::LayerKind;
use crate::meta::CloudMapMeta;
use crate::output::{check_output, ensure_not_input, write_atomic};
use crate::structure::{StructureBand, STRUCTURE_NODATA};

use super::bands::stream_bands;
use super::stats::Stats;
use super::Plan;

/// Descriptions of a GeoTIFF CloudMap's bands, in band order (the PNG's R, G, B, A).
pub const LAYER_BANDS: [&str; 4] = [
    "low cloud coverage",
    "middle cloud coverage",
    "high cloud coverage",
    "total cloud coverage (max of the layers)",
];

/// The GDAL metadata item under which a GeoTIFF CloudMap carries its sidecar's JSON.
pub const GEOTIFF_META_ITEM: &str = "STRATUS_CLOUDMAP";

impl Plan {
    /// Stream the map to a GeoTIFF at `tif_path` ([`crate::geotiff`]: tiled, with overviews,
    /// COG layout, EPSG:4326), written atomically ([`crate::output::write_atomic`]); it may
    /// not be the forecast file read. No sidecar is written: the sidecar's content (layers,
    /// times, source) is carried in the file as the GDAL metadata item `STRATUS_CLOUDMAP`.
    /// When the forecast held more than RH, the structure follows as a second image
    /// ([`Plan::geotiff_structure`]). Returns that metadata, coverage statistics filled in.
    /// `progress` is called with the number of coverage rows done.
    pub fn write_geotiff(
        &self,
        tif_path: &Path,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<CloudMapMeta> {
        check_output(tif_path)?;
        ensure_not_input(tif_path, &[self.source.as_path()])?;
        let name = tif_path
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| {
                IngestError::write(
                    tif_path,
                    "the file name is not valid UTF-8, and the map's metadata records it as text; choose a UTF-8 name",
                )
            })?;
        let spec = GeoTiffSpec {
            width: self.width as u32,
            height: self.height as u32,
            georef: GeoRef::of_region(&self.meta.region, self.width as u32, self.height as u32),
            band_names: LAYER_BANDS.map(String::from),
            deflate: true,
        };
        let structure = self.geotiff_structure();
        let mut done_meta = None;
        write_atomic(tif_path, |w| {
            let mut gt = GeoTiffWriter::new(spec).map_err(|e| e.to_string())?;
            if let Some((page, layout)) = &structure {
                gt.add_page(page.clone()).map_err(|e| e.to_string())?;
                stream_bands(
                    page.height as usize,
                    |a, b| {
                        let mut v = Vec::new();
                        for j in a..b {
                            self.sampler
                                .append_physical_row(layout, j, page.nodata, &mut v);
                        }
                        v
                    },
                    |p| gt.push_page_rows(&p).map_err(|e| e.to_string()),
                    |_| {},
                )?;
            }
            let mut st = Stats::default();
            stream_bands(
                self.height,
                |a, b| self.rows(a, b),
                |p| {
                    st.add(&p);
                    gt.push_rows(&p).map_err(|e| e.to_string())
                },
                progress,
            )?;
            let mut meta = self.meta.clone();
            st.apply(&mut meta);
            meta.image = name.to_string();
            meta.image_id = None;
            let json = serde_json::to_string(&meta).map_err(|e| e.to_string())?;
            gt.finish(w, &[(GEOTIFF_META_ITEM, &json)])
                .map_err(|e| e.to_string())?;
            done_meta = Some(meta);
            Ok(())
        })?;
        done_meta.ok_or_else(|| IngestError::write(tif_path, "nothing was written"))
    }

    /// The GeoTIFF's structure image and its bands, when the forecast held more than RH
    /// (`source.fields`): the structure images' lattice and values, decoded to physical units
    /// (docs/ingest.md, "GeoTIFF"). From RH alone the structure says little the coverage and
    /// the layers' bands do not (RH-column crossings on the standard atmosphere, each layer's
    /// default type, no wind), and the file stays the four coverage bands.
    pub fn geotiff_structure(&self) -> Option<(PageSpec, Vec<StructureBand>)> {
        if self.meta.source.fields.is_empty() {
            return None;
        }
        let kinds: Vec<LayerKind> = self.meta.layers.iter().map(|l| l.kind).collect();
        let layout = StructureBand::of_layers(&kinds);
        let g = self.sampler.lattice();
        let r = &self.meta.region;
        // The coverage image's longitudes, shifted by whole turns into [-180, 180) at the
        // region's west edge; the lattice moves with them.
        let shift = GeoRef::of_region(r, 1, 1).west - r.west;
        let bands = layout
            .iter()
            .map(|b| PageBand {
                description: b.description(),
                unit: b.unit().into(),
                items: b
                    .codes()
                    .map(|c| vec![("CODES".to_string(), c)])
                    .unwrap_or_default(),
            })
            .collect();
        let page = PageSpec {
            width: g.width,
            height: g.height,
            georef: GeoRef {
                west: g.west + shift,
                north: g.north,
                dx: g.dlon,
                dy: g.dlat,
            },
            bands,
            nodata: STRUCTURE_NODATA,
            metadata: vec![(
                "STRATUS_STRUCTURE".into(),
                "cloud structure of the coverage map (GTIFF_DIR:1): point samples on the \
                 forecast grid's lattice; read base, top and wind bilinear, type and source \
                 at the nearest pixel; altitudes in m above mean sea level"
                    .into(),
            )],
        };
        Some((page, layout))
    }
}
