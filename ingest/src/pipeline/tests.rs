//! The pipeline's tests over a whole plan (the GeoTIFF structure page against the images).

use std::path::Path;

use super::*;
use crate::forecast::Forecast;
use crate::layer::LayerKind;
use crate::spline::Interp;
use crate::structure::{StructureBand, STRUCTURE_NODATA};

/// A plan over the fixture's 6×5-point grid, from `fields`.
fn fixture_plan(dir: &Path, fields: &[crate::encode::Grib2Field]) -> Plan {
    let grib = dir.join("f.grib2");
    std::fs::write(&grib, crate::encode::encode_file(fields)).unwrap();
    let fc = Forecast::open(&grib, crate::forecast::LevelSelect::AllBelow(100.0)).unwrap();
    let opts = IngestOptions {
        region: Region::parse("46.5,49.5,10.5,14.5").unwrap(),
        width: 40,
        height: 30,
        rh_cr: [0.3; 3],
        interp: Interp::Spline,
    };
    Plan::new(&fc, &opts).unwrap()
}

#[test]
fn the_geotiff_structure_is_the_images_decoded_and_needs_more_than_rh() {
    use crate::encode::{fixtures, param};
    use crate::structure::{sample_to_altitude, sample_to_wind, unpack_source};
    use crate::weather::CloudType;
    let dir = tempfile::tempdir().unwrap();
    let all = fixtures::valid_rh_fields();
    let plan = fixture_plan(dir.path(), &all);
    let (page, layout) = plan
        .geotiff_structure()
        .expect("RH + gh has a structure page");
    let kinds: Vec<LayerKind> = plan.meta.layers.iter().map(|l| l.kind).collect();
    assert_eq!(layout, StructureBand::of_layers(&kinds));
    assert_eq!(layout.len(), 6 * kinds.len() + 2);
    assert_eq!(page.bands.len(), layout.len());
    let g = plan.structure_grid();
    assert_eq!((page.width, page.height), (g.width, g.height));
    assert_eq!(
        (
            page.georef.west,
            page.georef.north,
            page.georef.dx,
            page.georef.dy
        ),
        (g.west, g.north, g.dlon, g.dlat)
    );
    assert_eq!(page.bands[0].unit, "m");
    // Every pixel of every band: the structure images' samples, decoded.
    let ms = plan.build().structure.unwrap();
    let nd = STRUCTURE_NODATA;
    let m = |v: Option<f64>| v.map_or(nd, |v| v as f32);
    let mut with_value = 0;
    for j in 0..g.height as usize {
        let mut row = Vec::new();
        plan.sampler.append_physical_row(&layout, j, nd, &mut row);
        assert_eq!(row.len(), g.width as usize * layout.len());
        for (i, px) in row.chunks_exact(layout.len()).enumerate() {
            let p = j * g.width as usize + i;
            for (&b, &got) in layout.iter().zip(px) {
                let want = match b {
                    StructureBand::Base(k) => m(sample_to_altitude(ms.base[p][k.channel()])),
                    StructureBand::Top(k) => m(sample_to_altitude(ms.top[p][k.channel()])),
                    StructureBand::Type(k) => {
                        m(CloudType::from_code(ms.types[p][k.channel()]).map(|t| t.code() as f64))
                    }
                    StructureBand::Source(k) => {
                        m(unpack_source(ms.types[p][3], k.channel()).map(|s| s as u8 as f64))
                    }
                    // The fixture has no wind: none, not the images' 0 m/s.
                    StructureBand::WindU(k) | StructureBand::WindV(k) => {
                        assert!(plan.sampler.winds[k.channel()].is_none());
                        assert_eq!(sample_to_wind(ms.wind_u[p][k.channel()]), 0.0);
                        nd
                    }
                    StructureBand::ConvectiveBase => m(sample_to_altitude(ms.base[p][3])),
                    StructureBand::ConvectiveTop => m(sample_to_altitude(ms.top[p][3])),
                };
                assert_eq!(got.to_bits(), want.to_bits(), "{b:?} at ({i}, {j})");
                with_value += usize::from(got != nd);
            }
        }
    }
    assert!(with_value > 0);
    // RH alone (no gh): no structure page, so the file stays the coverage bands.
    let rh: Vec<_> = all
        .into_iter()
        .filter(|f| (f.category, f.number) == (param::RH.1, param::RH.2))
        .collect();
    let plan = fixture_plan(dir.path(), &rh);
    assert!(plan.meta.source.fields.is_empty());
    assert!(plan.geotiff_structure().is_none());
}
