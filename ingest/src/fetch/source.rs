//! Where a GFS run lives: the public sources' URL layouts (docs/fetch.md says where each fact
//! came from). All three mirror NCEP's production tree: under a base,
//! `gfs.YYYYMMDD/HH/atmos/gfs.tHHz.pgrb2.RES.fFFF`, with the inventory at the same name +
//! `.idx`.

use chrono::NaiveDate;

/// NCEP's own server: the last ~10 days of runs.
pub const NOMADS: &str = "https://nomads.ncep.noaa.gov/pub/data/nccf/com/gfs/prod/";
/// The NOAA Open Data Dissemination bucket on AWS S3: the archive, from 2021 in this layout.
pub const AWS: &str = "https://noaa-gfs-bdp-pds.s3.amazonaws.com/";
/// The same archive on Google Cloud Storage.
pub const GOOGLE: &str = "https://storage.googleapis.com/global-forecast-system/";

/// One run of the model at one resolution, under a base URL.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// Ends with `/`.
    pub base: String,
    pub date: NaiveDate,
    pub cycle: u32,
    /// `0p25`, `0p50`, `1p00`, or any name the server has.
    pub resolution: String,
}

/// `--source`: `nomads`, `aws`, `google`, or an `http://`/`https://` base URL.
pub fn base_url(source: &str) -> Result<String, String> {
    let base = match source {
        "nomads" => NOMADS.to_string(),
        "aws" => AWS.to_string(),
        "google" => GOOGLE.to_string(),
        s if s.starts_with("http://") || s.starts_with("https://") => {
            let shown = redact(s);
            if s.chars().any(|c| c.is_whitespace() || c.is_control()) {
                return Err(format!("--source {shown:?} is not a URL"));
            }
            if host(s).is_empty() {
                return Err(format!(
                    "--source \"{shown}\" names no host: give a base URL such as http://mirror.example/gfs/"
                ));
            }
            s.to_string()
        }
        s => {
            return Err(format!(
                "--source \"{s}\" must be nomads, aws, google or an http(s):// base URL"
            ))
        }
    };
    Ok(if base.ends_with('/') {
        base
    } else {
        base + "/"
    })
}

/// The authority of an `http(s)://` URL (what lies between `//` and the next `/`, `?` or `#`)
/// and where it starts in `url`.
fn authority(url: &str) -> Option<(usize, &str)> {
    let start = url.find("://")? + 3;
    let rest = &url[start..];
    let end = rest.find(['/', '?', '#']).unwrap_or(rest.len());
    Some((start, &rest[..end]))
}

/// The host (and port) of an `http(s)://` URL, without any `user:password@`.
pub fn host(url: &str) -> &str {
    let Some((_, auth)) = authority(url) else {
        return "";
    };
    let host = auth.rsplit_once('@').map_or(auth, |(_, h)| h);
    // A port alone (`http://:80/`) is no host either.
    if host.starts_with(':') {
        ""
    } else {
        host
    }
}

/// `text` with the password of every URL in it hidden: `http://user:secret@host/` is shown as
/// `http://user:***@host/` (and `http://token@host/` as `http://***@host/`), in errors, logs and
/// progress alike.
pub fn redact(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some((start, auth)) = authority(rest) {
        let (head, tail) = rest.split_at(start);
        out.push_str(head);
        match auth.rsplit_once('@') {
            Some((user, host)) => {
                match user.split_once(':') {
                    Some((name, _)) => out.push_str(&format!("{name}:***@")),
                    None => out.push_str("***@"),
                }
                out.push_str(host);
            }
            None => out.push_str(auth),
        }
        rest = &tail[auth.len()..];
    }
    out.push_str(rest);
    out
}

/// A resolution name as it appears in the file name (`0p25`): letters and digits only, so it
/// cannot change the path.
pub fn check_resolution(s: &str) -> Result<(), String> {
    if s.is_empty() || s.len() > 16 || !s.chars().all(|c| c.is_ascii_alphanumeric()) {
        return Err(format!(
            "--resolution \"{s}\" must be a name like 0p25, 0p50 or 1p00"
        ));
    }
    Ok(())
}

impl Run {
    /// `gfs.tHHz.pgrb2.RES.fFFF`.
    pub fn file_name(&self, step: u32) -> String {
        format!(
            "gfs.t{:02}z.pgrb2.{}.f{:03}",
            self.cycle, self.resolution, step
        )
    }

    /// The step's GRIB2 file under the base: `gfs.YYYYMMDD/HH/atmos/gfs.tHHz.pgrb2.RES.fFFF`.
    pub fn file_path(&self, step: u32) -> String {
        format!(
            "gfs.{}/{:02}/atmos/{}",
            self.date.format("%Y%m%d"),
            self.cycle,
            self.file_name(step)
        )
    }

    /// The step's GRIB2 file.
    pub fn grib_url(&self, step: u32) -> String {
        format!("{}{}", self.base, self.file_path(step))
    }

    /// The step's inventory.
    pub fn idx_url(&self, step: u32) -> String {
        self.grib_url(step) + ".idx"
    }

    /// What the run's date field in the inventory reads: `YYYYMMDDHH`.
    pub fn idx_date(&self) -> String {
        format!("{}{:02}", self.date.format("%Y%m%d"), self.cycle)
    }

    /// The file written for a step: the source's name with the date in front (runs of
    /// different days never share a name) and `.grib2` after.
    pub fn out_name(&self, step: u32) -> String {
        format!(
            "gfs.{}.t{:02}z.pgrb2.{}.f{:03}.grib2",
            self.date.format("%Y%m%d"),
            self.cycle,
            self.resolution,
            step
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts() {
        let run = Run {
            base: base_url("aws").unwrap(),
            date: NaiveDate::from_ymd_opt(2024, 5, 1).unwrap(),
            cycle: 6,
            resolution: "0p25".into(),
        };
        assert_eq!(
            run.idx_url(3),
            "https://noaa-gfs-bdp-pds.s3.amazonaws.com/gfs.20240501/06/atmos/gfs.t06z.pgrb2.0p25.f003.idx"
        );
        assert_eq!(run.out_name(120), "gfs.20240501.t06z.pgrb2.0p25.f120.grib2");
        assert_eq!(
            base_url("http://127.0.0.1:1/x").unwrap(),
            "http://127.0.0.1:1/x/"
        );
        assert!(base_url("ftp://x").is_err());
        for no_host in [
            "http://",
            "https:///gfs",
            "http://user:pw@/x",
            "http://:80/",
        ] {
            assert!(
                base_url(no_host).unwrap_err().contains("names no host"),
                "{no_host}"
            );
        }
        let e = base_url("http://u:secret@/x").unwrap_err();
        assert!(!e.contains("secret"), "{e}");
        assert_eq!(
            redact("a http://u:secret@h:1/p and https://tok@h/q, http://h/r"),
            "a http://u:***@h:1/p and https://***@h/q, http://h/r"
        );
        assert_eq!(host("http://u:p@h:8/x"), "h:8");
        assert!(check_resolution("0p25").is_ok() && check_resolution("../x").is_err());
    }
}
