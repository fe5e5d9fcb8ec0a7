//! `lerobot_version`: a LeRobot layout only for `format = "parquet"` (the values themselves,
//! `"v2.1"` and `"v3.0"`, are checked when the spec is read).

use super::Checker;
use crate::spec::model::{LerobotVersion, OutputFormat, ProfileSpec};
use crate::spec::preset::Profile;

impl Checker<'_> {
    /// `lerobot_version` set on a profile that does not write LeRobot. A value inherited through
    /// `extends` from a parquet profile is ignored by a profile of another format.
    pub(super) fn lerobot_version(&mut self, name: &str, own: &ProfileSpec, p: &Profile) {
        let Some(version) = own.lerobot_version else {
            return;
        };
        if p.format != OutputFormat::Parquet {
            let message = format!(
                "`lerobot_version` needs `format = \"parquet\"` (a LeRobot dataset); profile \
                 `{name}` writes `{}`",
                p.format.name()
            );
            let help = (version == LerobotVersion::V21)
                .then(|| "set `format = \"parquet\"` to write a LeRobot v2.1 dataset".to_string());
            let at = ["profiles", name, "lerobot_version"];
            self.value(&at, message, "only for parquet", help);
        }
    }
}
