//! Cloud genera (WMO International Cloud Atlas) with stable small codes: what the type image,
//! the sidecar and the probe name. The rule that picks one is in `weather::kind`.

use serde::{Deserialize, Serialize};

use crate::layer::LayerKind;

/// A WMO cloud genus, or none. The code is 1 + the genus' figure in WMO code table 0500
/// (Ci 0 … Cb 9), so 0 stays "no cloud / unknown"; the renderer indexes its lookup table
/// with it, so codes never change meaning.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[repr(u8)]
pub enum CloudType {
    Cirrus = 1,
    /// Kept in the table for stable codes; the rule never gives it (sub-grid cells).
    Cirrocumulus = 2,
    Cirrostratus = 3,
    Altocumulus = 4,
    Altostratus = 5,
    Nimbostratus = 6,
    Stratocumulus = 7,
    Stratus = 8,
    Cumulus = 9,
    Cumulonimbus = 10,
}

impl CloudType {
    pub const ALL: [CloudType; 10] = [
        CloudType::Cirrus,
        CloudType::Cirrocumulus,
        CloudType::Cirrostratus,
        CloudType::Altocumulus,
        CloudType::Altostratus,
        CloudType::Nimbostratus,
        CloudType::Stratocumulus,
        CloudType::Stratus,
        CloudType::Cumulus,
        CloudType::Cumulonimbus,
    ];

    /// Largest valid code; 0 is "none".
    pub const MAX_CODE: u8 = 10;

    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The type of a code; `None` for 0 (no cloud) and for codes outside the table.
    pub fn from_code(c: u8) -> Option<CloudType> {
        Self::ALL.get((c as usize).checked_sub(1)?).copied()
    }

    pub const fn name(self) -> &'static str {
        match self {
            CloudType::Cirrus => "cirrus",
            CloudType::Cirrocumulus => "cirrocumulus",
            CloudType::Cirrostratus => "cirrostratus",
            CloudType::Altocumulus => "altocumulus",
            CloudType::Altostratus => "altostratus",
            CloudType::Nimbostratus => "nimbostratus",
            CloudType::Stratocumulus => "stratocumulus",
            CloudType::Stratus => "stratus",
            CloudType::Cumulus => "cumulus",
            CloudType::Cumulonimbus => "cumulonimbus",
        }
    }

    /// The type a layer gets when the file holds nothing to tell (RH-only files, version 1
    /// and 2 maps): the layer's commonest stratiform genus.
    pub const fn layer_default(kind: LayerKind) -> CloudType {
        match kind {
            LayerKind::Low => CloudType::Stratocumulus,
            LayerKind::Middle => CloudType::Altostratus,
            LayerKind::High => CloudType::Cirrus,
        }
    }
}
