//! `cleanup_temps`, what the binary's INT/TERM/HUP handler calls: it removes the temporary
//! files of writes in progress and stops any further write. It ends all writing in the
//! process, so it has this test binary to itself.

use std::io::Write;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use stratus_ingest::error::IngestError;
use stratus_ingest::output::{cleanup_temps, live_temps, write_atomic};

#[test]
fn cleanup_removes_the_temporaries_of_writes_in_progress_and_stops_new_ones() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.png");
    fs_write_previous(&out);
    let (wrote, wrote_rx) = mpsc::channel();
    let (go_on, go_on_rx) = mpsc::channel::<()>();
    let writer = std::thread::spawn({
        let out = out.clone();
        move || {
            write_atomic(&out, |w| {
                w.write_all(&[7u8; 1 << 20]).map_err(|e| e.to_string())?;
                w.flush().map_err(|e| e.to_string())?;
                wrote.send(()).map_err(|e| e.to_string())?;
                // The "signal" arrives while the file is being written.
                go_on_rx.recv().map_err(|e| e.to_string())
            })
        }
    });
    wrote_rx.recv().unwrap();
    let temps = live_temps();
    assert_eq!(temps.len(), 1, "{temps:?}");
    assert!(temps[0].exists());
    assert_eq!(cleanup_temps(), 1);
    assert!(!temps[0].exists(), "the temporary survived the cleanup");
    go_on.send(()).unwrap();
    let e = writer.join().unwrap().unwrap_err();
    assert!(matches!(e, IngestError::Interrupted { .. }), "{e}");
    // The previous output is untouched and nothing else is in the folder.
    assert_eq!(std::fs::read(&out).unwrap(), b"previous");
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 1, "{names:?}");
    // After the cleanup no write starts.
    let t = Instant::now();
    let e = write_atomic(&dir.path().join("n.png"), |_| Ok(())).unwrap_err();
    assert!(e.to_string().contains("interrupted"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(1));
    assert!(!dir.path().join("n.png").exists());
}

fn fs_write_previous(p: &std::path::Path) {
    std::fs::write(p, b"previous").unwrap();
}
