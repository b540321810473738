//! The forecast's vertical structure and cloud types (issue 13, DESIGN §7): per grid point and
//! layer, cloud base and top with their source ([`grid`]), a WMO genus from a documented rule
//! over the convective and stability fields ([`kind`]), and the layer's wind, from the fields
//! the GRIB file holds besides RH ([`inputs`]). The pipeline samples these onto the map's
//! pixels (`pipeline::pixels`) and stores them in the images `structure` describes.

pub mod grid;
pub mod inputs;
pub mod kind;

pub use crate::cloud::CloudType;
pub use crate::layer::PointSource;
pub use grid::{GridStructure, LayerSpec};
pub use inputs::{RhLevel, WeatherInputs};
pub use kind::{classify, ColumnFacts};
