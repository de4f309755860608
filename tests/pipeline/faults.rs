//! Output safety under scripted faults: what a user keeps around, beside and behind `--out`
//! (folders and files at the names altrep writes, symbolic and hard links at every level,
//! read-only paths, a full disk, interrupts, concurrent runs, edits between runs) is never
//! changed, and nothing outside `--out` appears or goes.
//!
//! Read-only paths and a full disk need root (the immutable attribute, bind and tmpfs mounts;
//! as another user a folder's mode stands in for read-only). Where a fault cannot be made, the
//! case says so on stderr ("NOT SIMULATED") and checks only that the run does no harm.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::os::unix::fs::symlink;
use std::os::unix::process::ExitStatusExt;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::process::Stdio;
use std::sync::OnceLock;

use super::*;
use altrep::asset::STAGING_DIR;
use altrep::pipeline::{LOCK_FILE, RunSummary};

mod check;
mod trap;

use check::*;
use trap::*;

/// Faults set up around `--out` of runs in this process: the user's files and folders at the
/// names altrep writes, in a folder it never ran in and in one it did; symbolic links at every
/// level; hard links to its outputs; edits, stray files and leftovers between runs; read-only
/// folders and files (immutable attribute or read-only bind mount, as root); a full disk (a
/// small tmpfs, filled at several points, or out of inodes); missing or linked inputs; a held
/// lock and two runs at once. Each case checks that nothing panics, the run ends as expected
/// (success, or a typed error naming the offending path), every file of the user's is byte for
/// byte the same, nothing outside the folder the files land in appears, changes or goes, and
/// every asset folder the run touched is complete.
#[cfg(unix)]
#[test]
fn faults_around_the_output_folder_do_no_harm() {
    let cases: &[(&str, Setup)] = &[
        // The user's things where altrep writes, in a folder it never ran in.
        ("user report.json in a new --out", |t| {
            Plan::lib(Expect::Refused(t.user("out/report.json", b"{\"mine\": 1}")))
        }),
        ("user pictures folder in a new --out", |t| {
            t.user("out/pictures/holiday.png", b"not a png");
            Plan::lib(Expect::Refused(t.at("out/pictures")))
        }),
        ("user .staging folder in a new --out", |t| {
            t.user("out/.staging/draft.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/.staging")))
        }),
        ("user file named like the lock file", |t| {
            t.user("out/.altrep.lock", b"mine, not a lock");
            Plan::lib(Expect::Ok)
        }),
        ("user folder at an asset's name, with notes", |t| {
            t.user("out/pear/notes.txt", b"mine");
            Plan::lib(Expect::Ok)
        }),
        ("user folder at an asset/representation name", |t| {
            t.user("out/pear/parallax/notes.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/pear/parallax")))
        }),
        ("empty asset.json", |t| {
            Plan::lib(Expect::Refused(t.user("out/pear/parallax/asset.json", b"")))
        }),
        ("garbage asset.json", |t| {
            let p = t.user(
                "out/chair/octree/asset.json",
                &[0xff, 0x00, 0x9c, 0x7b, 0x0a],
            );
            Plan::lib(Expect::Refused(p))
        }),
        ("valid JSON asset.json that is not altrep's", |t| {
            let p = t.user(
                "out/pear/parallax/asset.json",
                b"{\"name\": \"pear\", \"v\": 3}",
            );
            Plan::lib(Expect::Refused(p))
        }),
        ("another tool's asset.json (an image catalogue)", |t| {
            let p = t.user(
                "out/chair/octree/asset.json",
                br#"{"info": {"author": "xcode", "version": 1}, "images": [{"filename": "chair.png", "idiom": "universal"}]}"#,
            );
            t.user("out/chair/octree/chair.png", b"not a png");
            Plan::lib(Expect::Refused(p))
        }),
        ("a newer altrep's asset folder", |t| {
            t.prior();
            let p = t.at("out/pear/parallax/asset.json");
            let mut v: serde_json::Value =
                serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
            v["format_version"] = serde_json::json!([2, 0]);
            v["a_field_of_format_2"] = true.into();
            std::fs::write(&p, v.to_string()).unwrap();
            t.protect.push(p.clone());
            Plan::lib(Expect::Refused(p))
        }),
        ("asset.json a folder", |t| {
            t.user("out/chair/octree/asset.json/inner.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/chair/octree/asset.json")))
        }),
        ("a file where an asset folder goes", |t| {
            Plan::lib(Expect::Refused(t.user("out/chair", b"mine")))
        }),
        ("a file where a representation folder goes", |t| {
            Plan::lib(Expect::Refused(t.user("out/chair/octree", b"mine")))
        }),
        ("report.md a folder, in a folder altrep ran in", |t| {
            t.prior();
            remove(t, "out/report.md");
            t.user("out/report.md/inner.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/report.md")))
        }),
        ("pictures a file, in a folder altrep ran in", |t| {
            t.prior();
            remove(t, "out/pictures");
            Plan::lib(Expect::Refused(t.user("out/pictures", b"mine")))
        }),
        (".staging a file, in a folder altrep ran in", |t| {
            t.prior();
            let _ = std::fs::remove_dir_all(t.at("out/.staging"));
            Plan::lib(Expect::Refused(t.user("out/.staging", b"mine")))
        }),
        ("the lock file a folder", |t| {
            t.user("out/.altrep.lock/inner.txt", b"mine");
            Plan::lib(Expect::Refused(t.at("out/.altrep.lock")))
        }),
        // The user's things beside altrep's.
        ("user files beside altrep's, in a folder it ran in", |t| {
            t.prior();
            t.user("out/notes.txt", b"mine");
            t.user("out/pear/notes.txt", b"mine");
            t.user("out/pictures/mine.png", b"mine");
            Plan::forced(Expect::Ok)
        }),
        ("a user folder of other things in --out", |t| {
            t.user("out/mine/photo.png", b"mine");
            t.user("out/mine/deep/x.txt", b"mine");
            Plan::lib(Expect::Ok)
        }),
        ("an asset no longer in the scene", |t| {
            t.prior();
            t.protect.push(t.at("out/pear/parallax/asset.json"));
            t.protect.push(t.at("out/pear/parallax/view0-albedo.png"));
            t.scene = TINY
                .split("[[asset]]")
                .nth(2)
                .map(|c| format!("[[asset]]{c}"))
                .unwrap();
            Plan::lib(Expect::Ok)
        }),
        ("an asset folder the user renamed", |t| {
            t.prior();
            std::fs::rename(t.at("out/pear/parallax"), t.at("out/pear/parallax-mine")).unwrap();
            t.protect.push(t.at("out/pear/parallax-mine/asset.json"));
            Plan::lib(Expect::Ok)
        }),
        // Symbolic links at every level.
        ("asset folder a link to a folder outside", |t| {
            t.user("outside/elsewhere/parallax/notes.txt", b"mine");
            let p = t.link(t.at("outside/elsewhere"), "out/pear");
            Plan::lib(Expect::Refused(p))
        }),
        (
            "representation folder a link to altrep's asset outside",
            |t| {
                let elsewhere = t.at("outside/elsewhere");
                assert!(run_scene(&t.parsed(), &options(&elsewhere)).unwrap().ok());
                let p = t.link(elsewhere.join("pear/parallax"), "out/pear/parallax");
                Plan::lib(Expect::Refused(p))
            },
        ),
        ("asset.json a link to a file outside", |t| {
            let p = t.link(t.at("outside/keep.txt"), "out/chair/octree/asset.json");
            Plan::lib(Expect::Refused(p))
        }),
        ("asset folder a dangling link", |t| {
            Plan::lib(Expect::Refused(t.link(t.at("outside/nowhere"), "out/pear")))
        }),
        ("asset folders linked in a loop", |t| {
            t.link(t.at("out/pear"), "out/pear2");
            Plan::lib(Expect::Refused(t.link(t.at("out/pear2"), "out/pear")))
        }),
        ("representation folder a link to itself", |t| {
            Plan::lib(Expect::Refused(t.link("octree", "out/chair/octree")))
        }),
        ("pictures a link to a folder outside", |t| {
            t.user("outside/photos/holiday.png", b"mine");
            Plan::lib(Expect::Refused(
                t.link(t.at("outside/photos"), "out/pictures"),
            ))
        }),
        (
            "report.md a link to a file outside, in a folder altrep ran in",
            |t| {
                t.prior();
                remove(t, "out/report.md");
                Plan::lib(Expect::Refused(
                    t.link(t.at("outside/keep.txt"), "out/report.md"),
                ))
            },
        ),
        ("report.json a dangling link", |t| {
            let p = t.link(t.at("outside/summary.json"), "out/report.json");
            Plan::lib(Expect::Refused(p))
        }),
        (
            ".staging a link to a folder outside, in a folder altrep ran in",
            |t| {
                t.prior();
                let _ = std::fs::remove_dir_all(t.at("out/.staging"));
                t.user("outside/drafts/a.txt", b"mine");
                Plan::lib(Expect::Refused(
                    t.link(t.at("outside/drafts"), "out/.staging"),
                ))
            },
        ),
        ("the lock file a link to a file outside", |t| {
            Plan::lib(Expect::Refused(
                t.link(t.at("outside/keep.txt"), "out/.altrep.lock"),
            ))
        }),
        ("a picture a link to a file outside", |t| {
            t.prior();
            remove(t, "out/pictures/pear-parallax.png");
            t.user("outside/holiday.png", b"the user's photo");
            t.link(
                t.at("outside/holiday.png"),
                "out/pictures/pear-parallax.png",
            );
            Plan::forced(Expect::Ok)
        }),
        ("a picture a dangling link out of --out", |t| {
            t.prior();
            remove(t, "out/pictures/chair-octree.png");
            t.link(t.at("outside/new.png"), "out/pictures/chair-octree.png");
            Plan::forced(Expect::Ok)
        }),
        ("a folder of the user's at a picture's name", |t| {
            t.prior();
            remove(t, "out/pictures/pear-parallax.png");
            t.user("out/pictures/pear-parallax.png/mine.txt", b"mine");
            Plan::forced(Expect::Fails(t.at("out/pictures/pear-parallax.png")))
        }),
        ("a picture edited by the user, then a forced rerun", |t| {
            t.prior();
            overwrite(t, "out/pictures/chair-octree.png", b"painted over");
            Plan::forced(Expect::Ok)
        }),
        (
            "altrep's temporary file name a link to a file outside",
            |t| {
                t.prior();
                let name = format!("out/.report.md.tmp{}", std::process::id());
                let p = t.link(t.at("outside/keep.txt"), &name);
                Plan::lib(Expect::Ok).gone(p)
            },
        ),
        ("a data file replaced by a link to a file outside", |t| {
            t.prior();
            remove(t, "out/pear/parallax/view2-depth.png");
            t.link(
                t.at("outside/keep.txt"),
                "out/pear/parallax/view2-depth.png",
            );
            Plan::lib(Expect::Ok)
        }),
        ("a link to a folder outside inside an asset folder", |t| {
            t.prior();
            t.user("outside/photos/a.png", b"mine");
            let p = t.link(t.at("outside/photos"), "out/chair/octree/photos");
            Plan::lib(Expect::Ok).gone(p)
        }),
        // Hard links: the user's copies of altrep's outputs.
        ("a picture hard-linked outside, then a changed scene", |t| {
            t.prior();
            hard_copy(t, "out/pictures/pear-parallax.png", "kept.png");
            t.scene = changed();
            Plan::lib(Expect::Ok)
        }),
        ("report.md hard-linked outside, then a rerun", |t| {
            t.prior();
            hard_copy(t, "out/report.md", "report-kept.md");
            Plan::lib(Expect::Ok)
        }),
        (
            "a data file hard-linked outside, then a changed scene",
            |t| {
                t.prior();
                hard_copy(t, "out/pear/parallax/view0-albedo.png", "kept.png");
                t.scene = changed();
                Plan::lib(Expect::Ok)
            },
        ),
        (
            "asset.json hard-linked outside, then a changed scene",
            |t| {
                t.prior();
                hard_copy(t, "out/pear/parallax/asset.json", "kept.json");
                t.scene = changed();
                Plan::lib(Expect::Ok)
            },
        ),
        ("the lock file hard-linked to a file outside", |t| {
            std::fs::create_dir_all(&t.out).unwrap();
            std::fs::hard_link(t.at("outside/keep.txt"), t.at("out/.altrep.lock")).unwrap();
            Plan::lib(Expect::Ok)
        }),
        (
            "a stray hard link to a user's file in an asset folder",
            |t| {
                t.prior();
                let p = t.at("out/chair/octree/keep.txt");
                std::fs::hard_link(t.at("outside/keep.txt"), &p).unwrap();
                Plan::lib(Expect::Ok).gone(p)
            },
        ),
        // Edits and leftovers between runs: altrep's own folders are rebuilt.
        ("a stray file in an asset folder", |t| {
            t.prior();
            overwrite(t, "out/chair/octree/notes.txt", b"x");
            Plan::lib(Expect::Ok).gone(t.at("out/chair/octree/notes.txt"))
        }),
        ("a stray folder in an asset folder", |t| {
            t.prior();
            t.dir("out/pear/parallax/extra");
            overwrite(t, "out/pear/parallax/extra/deep.txt", b"x");
            Plan::lib(Expect::Ok).gone(t.at("out/pear/parallax/extra"))
        }),
        ("a data file altered by one byte", |t| {
            t.prior();
            let p = t.at("out/chair/octree/octree.bin");
            let mut b = std::fs::read(&p).unwrap();
            b[20] ^= 0x10;
            std::fs::write(&p, b).unwrap();
            Plan::lib(Expect::Ok)
        }),
        ("a data file deleted", |t| {
            t.prior();
            remove(t, "out/pear/parallax/view1-depth.png");
            Plan::lib(Expect::Ok)
        }),
        ("asset.json edited", |t| {
            t.prior();
            let p = t.at("out/pear/parallax/asset.json");
            let mut v: serde_json::Value =
                serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
            v["metadata"]["edited_by_hand"] = true.into();
            std::fs::write(&p, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
            Plan::lib(Expect::Ok)
        }),
        ("asset.json cut short", |t| {
            t.prior();
            let p = t.at("out/chair/octree/asset.json");
            let b = std::fs::read(&p).unwrap();
            std::fs::write(&p, &b[..b.len() / 2]).unwrap();
            Plan::lib(Expect::Refused(p))
        }),
        ("a leftover staging folder of a killed run", |t| {
            t.prior();
            t.dir("out/.staging/pear.parallax.99999.0");
            overwrite(
                t,
                "out/.staging/pear.parallax.99999.0/view0-albedo.png",
                b"half",
            );
            Plan::lib(Expect::Ok).gone(t.at("out/.staging/pear.parallax.99999.0"))
        }),
        ("temporary files left by a run killed while it wrote", |t| {
            t.prior();
            overwrite(t, "out/.report.md.tmp99999", b"half a rep");
            overwrite(t, "out/pictures/.pear-parallax.png.tmp99999", b"half a png");
            t.user("out/.notes.tmp5", b"mine");
            Plan::lib(Expect::Ok)
                .gone(t.at("out/.report.md.tmp99999"))
                .gone(t.at("out/pictures/.pear-parallax.png.tmp99999"))
        }),
        // Read-only folders and files.
        ("--out a read-only empty folder", |t| {
            let out = t.dir("out");
            if t.read_only(&out) {
                Plan::lib(Expect::Stops(out.join(LOCK_FILE)))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("--out a read-only bind mount after a run", |t| {
            t.prior();
            let out = t.out.clone();
            if t.read_only_mount(&out) {
                Plan::lib(Expect::Stops(out.join(LOCK_FILE)))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("--out immutable after a run", |t| {
            t.prior();
            let out = t.out.clone();
            if t.read_only(&out) {
                Plan::lib(Expect::Stops(out.join(STAGING_DIR)))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("pictures read-only, a forced rerun", |t| {
            t.prior();
            let p = t.at("out/pictures");
            if t.read_only(&p) {
                Plan::forced(Expect::Fails(p))
            } else {
                Plan::forced(Expect::Either)
            }
        }),
        (
            "an asset's folder a read-only bind mount, a forced rerun",
            |t| {
                t.prior();
                let p = t.at("out/chair");
                if t.read_only_mount(&p) {
                    Plan::forced(Expect::Fails(p.join("octree")))
                } else {
                    Plan::forced(Expect::Either)
                }
            },
        ),
        ("report.md read-only", |t| {
            t.prior();
            let p = t.at("out/report.md");
            if t.read_only(&p) {
                Plan::lib(Expect::Fails(p))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("an asset folder read-only, a forced rerun", |t| {
            t.prior();
            let p = t.at("out/pear/parallax");
            if t.read_only(&p) {
                Plan::forced(Expect::Fails(p))
            } else {
                Plan::forced(Expect::Either)
            }
        }),
        ("a read-only stray file in an asset folder", |t| {
            t.prior();
            overwrite(t, "out/pear/parallax/notes.txt", b"x");
            let p = t.at("out/pear/parallax/notes.txt");
            if t.read_only(&p) {
                Plan::lib(Expect::Fails(t.at("out/.staging")))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        (".staging read-only with a leftover, after a run", |t| {
            t.prior();
            t.dir("out/.staging/pear.parallax.99999.0");
            overwrite(
                t,
                "out/.staging/pear.parallax.99999.0/view0-albedo.png",
                b"half",
            );
            let p = t.at("out/.staging");
            if t.read_only(&p) {
                Plan::lib(Expect::Stops(p))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("a user's empty folder at an asset's name, read-only", |t| {
            let p = t.dir("out/pear");
            if t.read_only(&p) {
                Plan::lib(Expect::Fails(p.join("parallax")))
            } else {
                Plan::lib(Expect::Either)
            }
        }),
        ("--out append-only", |t| {
            let out = t.dir("out");
            let tmp = out.join(format!(".report.json.tmp{}", std::process::id()));
            if t.append_only(&out) {
                Plan::lib(Expect::Fails(out.join("report.json"))).extra(tmp)
            } else {
                Plan::lib(Expect::Either).extra(tmp)
            }
        }),
        ("manifest and mesh in a read-only folder", |t| {
            t.manifest = t.at("input/scene.toml");
            t.scene = mesh_scene("box.obj");
            t.user("input/box.obj", BOX_OBJ.as_bytes());
            let scene = t.scene.clone();
            t.user("input/scene.toml", scene.as_bytes());
            let input = t.at("input");
            t.read_only(&input);
            Plan::lib(Expect::Ok)
        }),
        // Inputs.
        ("the mesh a link to a file outside", |t| {
            t.user("outside/box.obj", BOX_OBJ.as_bytes());
            t.link(t.at("outside/box.obj"), "box.obj");
            t.scene = mesh_scene("box.obj");
            Plan::lib(Expect::Ok)
        }),
        ("the mesh missing", |t| {
            t.scene = mesh_scene("missing.obj");
            Plan::lib(Expect::Fails(t.at("missing.obj")))
        }),
        ("the mesh a folder", |t| {
            t.dir("box.obj");
            t.scene = mesh_scene("box.obj");
            Plan::lib(Expect::Fails(t.at("box.obj")))
        }),
        // A full disk: a tmpfs as --out, filled by a file of the user's.
        ("full disk: no page free", |t| {
            let ok = t.full_disk(0);
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("full disk: a quarter of a run's pages free", |t| {
            let ok = t.full_disk(clean().pages / 4);
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("full disk: half of a run's pages free", |t| {
            let ok = t.full_disk(clean().pages / 2);
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("full disk: one page short of a run", |t| {
            let ok = t.full_disk(clean().pages - 1);
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("no inode left", |t| {
            let out = t.out.clone();
            let n = clean().entries / 2;
            let ok = t.tmpfs(&out, &format!("size=4m,nr_inodes={n}"));
            Plan::lib(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("full disk under a forced rerun of a changed scene", |t| {
            let out = t.out.clone();
            let ok = t.tmpfs(&out, &format!("size={}k", 4 * (clean().pages + 8)));
            t.prior();
            if ok {
                // The rest of the disk: a file of the user's.
                use std::io::Write;
                let filler = t.at("out/filler.bin");
                let mut f = std::fs::File::create(&filler).unwrap();
                while f.write_all(&[7; 4096]).is_ok() {}
                drop(f);
                t.protect.push(filler);
            }
            t.scene = changed();
            Plan::forced(if ok { Expect::DiskFull } else { Expect::Either })
        }),
        ("--out deep inside a full disk", |t| {
            let disk = t.at("disk");
            let ok = t.tmpfs(&disk, "size=8k");
            if ok {
                t.user("disk/filler.bin", &[7; 4096]);
            }
            t.out = t.at("disk/a/b/out");
            t.lands = t.out.clone();
            let plan = Plan::lib(if ok { Expect::DiskFull } else { Expect::Either });
            plan.extra(t.at("disk/a")).extra(t.at("disk/a/b"))
        }),
        ("full disk, then room: the rerun completes", |t| {
            let ok = t.full_disk(clean().pages / 3);
            Plan::custom(move |t| {
                let m = t.parsed();
                let first = lib_run(&m, &t.out, false, true);
                if !ok {
                    return first;
                }
                if first.panicked.is_some() || first.result.is_ok() {
                    return first;
                }
                let size = format!("remount,size={}k", 4 * (clean().pages + 64));
                assert!(sh(
                    "mount",
                    &["-o".as_ref(), size.as_ref(), t.out.as_os_str()]
                ));
                let second = lib_run(&m, &t.out, false, true);
                match (second.result, equals_clean(&t.lands)) {
                    (Ok(s), Ok(())) => Observed::ok(format!(
                        "the full disk: {}; with room: {s}, equal to a clean run",
                        first
                            .result
                            .unwrap_err()
                            .chars()
                            .take(100)
                            .collect::<String>()
                    )),
                    (Err(e), _) | (_, Err(e)) => Observed::err(e),
                }
            })
        }),
        // Concurrent runs.
        (
            "a run while another holds the lock, beside its staging",
            |t| {
                t.user(
                    "out/.staging/pear.parallax.1.0/view0-albedo.png",
                    b"being written",
                );
                let lock = t.user("out/.altrep.lock", b"");
                Plan::with(
                    Run::Custom(Box::new(move |t| {
                        let held = std::fs::File::options().write(true).open(&lock).unwrap();
                        held.try_lock().unwrap();
                        lib_run(&t.parsed(), &t.out, false, true)
                    })),
                    Expect::Stops(t.at("out/.altrep.lock")),
                )
            },
        ),
        ("two runs at once in one folder", |_| {
            Plan::custom(|t| {
                let m = t.parsed();
                let (a, b) = std::thread::scope(|s| {
                    let a = s.spawn(|| lib_run(&m, &t.out, false, true));
                    let b = s.spawn(|| lib_run(&m, &t.out, false, true));
                    (a.join().unwrap(), b.join().unwrap())
                });
                let locked = |o: &Observed| matches!(&o.result, Err(e) if e.contains("lock held"));
                for o in [&a, &b] {
                    if o.panicked.is_some() || (o.result.is_err() && !locked(o)) {
                        return Observed::err(format!("{:?}", o.result));
                    }
                }
                if locked(&a) && locked(&b) {
                    return Observed::err("both runs were refused");
                }
                match equals_clean(&t.lands) {
                    Ok(()) => Observed::ok(format!(
                        "{:?} and {:?}; the files are a clean run's",
                        a.result, b.result
                    )),
                    Err(e) => Observed::err(e),
                }
            })
        }),
    ];
    let failures = run_cases(cases);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Faults that need the command: `--out` itself a link (to a folder, to a file, dangling, in a
/// loop) or a file, its parent a link, missing parents; a missing manifest; `--json` a folder, a
/// read-only file or in a missing folder; interrupts (SIGINT, SIGTERM, SIGKILL) when the lock
/// exists, while files are staged, once an asset is committed, once a picture is written and
/// at seeded points of a run, each followed by a rerun that must equal a clean run; a run
/// stopped while it holds the lock; two commands at once. Each case checks what
/// [`faults_around_the_output_folder_do_no_harm`] checks, and that the command does not panic.
#[cfg(unix)]
#[test]
fn faults_of_the_command_do_no_harm() {
    let cases: &[(&str, Setup)] = &[
        ("--out a link to an empty folder outside", |t| {
            t.dir("outside/target");
            t.link(t.at("outside/target"), "out");
            Plan::bin(&[], Expect::Ok)
        }),
        (
            "--out a link to a folder outside holding the user's report.md",
            |t| {
                t.user("outside/target/report.md", b"my notes");
                t.link(t.at("outside/target"), "out");
                Plan::bin(&[], Expect::Refused(t.at("out/report.md")))
            },
        ),
        ("--out a dangling link", |t| {
            t.link(t.at("outside/nowhere"), "out");
            Plan::bin(&[], Expect::Stops(t.out.clone()))
        }),
        ("--out a link to a file outside", |t| {
            t.link(t.at("outside/keep.txt"), "out");
            Plan::bin(&[], Expect::Stops(t.out.clone()))
        }),
        ("--out a link in a loop", |t| {
            t.link(t.at("out"), "out2");
            t.link(t.at("out2"), "out");
            Plan::bin(&[], Expect::Stops(t.out.clone()))
        }),
        ("--out's parent a link to a folder outside", |t| {
            t.dir("outside/real");
            t.link(t.at("outside/real"), "via");
            t.out = t.at("via/out");
            t.lands = t.at("outside/real/out");
            Plan::bin(&[], Expect::Ok)
        }),
        ("--out a file", |t| {
            let out = t.user("out", b"mine");
            Plan::bin(&[], Expect::Stops(out))
        }),
        ("--out inside a file", |t| {
            t.user("afile", b"mine");
            t.out = t.at("afile/out");
            t.lands = t.out.clone();
            Plan::bin(&[], Expect::Stops(t.out.clone()))
        }),
        ("--out with missing parents", |t| {
            t.out = t.at("a/b/out");
            t.lands = t.out.clone();
            Plan::bin(&[], Expect::Ok)
                .extra(t.at("a"))
                .extra(t.at("a/b"))
        }),
        ("a missing manifest", |t| {
            let missing = t.at("none.toml");
            let args = [
                "precompute".as_ref(),
                missing.as_os_str(),
                "--out".as_ref(),
                t.out.as_os_str(),
            ];
            Plan::with(
                Run::BinArgs(args.iter().map(|a| a.into()).collect()),
                Expect::Stops(missing.clone()),
            )
        }),
        ("--json an existing folder", |t| {
            let p = t.dir("outside/summary");
            Plan::bin(
                &["--json".as_ref(), p.as_os_str()],
                Expect::Stops(p.clone()),
            )
        }),
        ("--json a read-only file", |t| {
            let p = t.user("outside/summary.json", b"{\"earlier\": true}");
            if t.read_only(&p) {
                Plan::bin(
                    &["--json".as_ref(), p.as_os_str()],
                    Expect::Stops(p.clone()),
                )
            } else {
                Plan::bin(&["--json".as_ref(), p.as_os_str()], Expect::Either)
            }
        }),
        ("--json in a missing folder", |t| {
            let p = t.at("outside/none/summary.json");
            Plan::bin(
                &["--json".as_ref(), p.as_os_str()],
                Expect::Stops(p.clone()),
            )
        }),
        ("--json a new file beside --out", |t| {
            let p = t.at("outside/summary.json");
            Plan::bin(&["--json".as_ref(), p.as_os_str()], Expect::Ok).extra(p)
        }),
        // Interrupts, each followed by a rerun that must equal a clean run.
        ("SIGKILL once the lock file exists", |_| {
            interrupted("KILL", When::Lock)
        }),
        ("SIGINT while files are staged", |_| {
            interrupted("INT", When::Staged)
        }),
        ("SIGTERM once an asset is committed", |_| {
            interrupted("TERM", When::Committed)
        }),
        ("SIGKILL once a picture is written", |_| {
            interrupted("KILL", When::Picture)
        }),
        ("SIGINT at seeded point 1", |_| {
            interrupted("INT", When::After(share(1)))
        }),
        ("SIGTERM at seeded point 2", |_| {
            interrupted("TERM", When::After(share(2)))
        }),
        ("SIGKILL at seeded point 3", |_| {
            interrupted("KILL", When::After(share(3)))
        }),
        ("SIGINT at seeded point 4", |_| {
            interrupted("INT", When::After(share(4)))
        }),
        ("SIGKILL at seeded point 5", |_| {
            interrupted("KILL", When::After(share(5)))
        }),
        ("SIGKILL of a forced rerun over a complete output", |t| {
            t.prior();
            Plan::custom(|t| {
                let r = interrupt(t, "KILL", When::After(share(6)), &["--force".as_ref()])
                    .and_then(|landed| {
                        finish(t)?;
                        equals_clean(&t.lands)?;
                        Ok(format!("killed mid-run: {landed}; earlier folders complete; the rerun equals a clean run"))
                    });
                r.map_or_else(Observed::err, Observed::ok)
            })
        }),
        ("SIGKILL, SIGTERM of the rerun, then a rerun", |_| {
            Plan::custom(|t| {
                let r = interrupt(t, "KILL", When::Staged, &[])
                    .and_then(|a| Ok((a, interrupt(t, "TERM", When::Committed, &[])?)))
                    .and_then(|(a, b)| {
                        finish(t)?;
                        equals_clean(&t.lands)?;
                        Ok(format!(
                            "killed mid-run: {a}, {b}; the last rerun equals a clean run"
                        ))
                    });
                r.map_or_else(Observed::err, Observed::ok)
            })
        }),
        // Concurrent runs.
        (
            "a run stopped while it holds the lock, and a second run",
            |_| {
                Plan::custom(|t| {
                    let mut child = precompute(t, &[])
                        .stdout(Stdio::null())
                        .stderr(Stdio::piped())
                        .spawn()
                        .unwrap();
                    let t0 = Instant::now();
                    // `pictures` is made once the lock is held and the folders checked.
                    while !t.lands.join("pictures").exists()
                        && child.try_wait().unwrap().is_none()
                        && t0.elapsed() < Duration::from_secs(30)
                    {
                        std::thread::sleep(Duration::from_micros(200));
                    }
                    let stopped = child.try_wait().unwrap().is_none()
                        && Command::new("kill")
                            .args(["-STOP", &child.id().to_string()])
                            .status()
                            .unwrap()
                            .success();
                    let second = lib_run(&t.parsed(), &t.out, false, true);
                    if stopped {
                        Command::new("kill")
                            .args(["-CONT", &child.id().to_string()])
                            .status()
                            .unwrap();
                    }
                    let first = bin_observed(&child.wait_with_output().unwrap());
                    if let Some(p) = first.panicked.or(second.panicked) {
                        return Observed::err(format!("panicked: {p}"));
                    }
                    if let Err(e) = &first.result {
                        return Observed::err(format!("the stopped run failed: {e}"));
                    }
                    match (&second.result, stopped) {
                        (Err(e), true) if e.contains("lock held") && e.contains(LOCK_FILE) => {}
                        (Ok(_), false) => {}
                        (r, _) => {
                            return Observed::err(format!(
                                "stopped: {stopped}; the second run: {r:?}"
                            ));
                        }
                    }
                    match equals_clean(&t.lands) {
                        Ok(()) => Observed::ok(format!(
                            "stopped: {stopped}; the second run: {:?}; the first ends, equal to a clean run",
                            second
                                .result
                                .map_err(|e| e.replace(&t.base.display().to_string(), "ROOT"))
                        )),
                        Err(e) => Observed::err(e),
                    }
                })
            },
        ),
        ("two commands at once in one folder", |_| {
            Plan::custom(|t| {
                let spawn = || {
                    precompute(t, &[])
                        .stdout(Stdio::null())
                        .stderr(Stdio::piped())
                        .spawn()
                        .unwrap()
                };
                let (a, b) = (spawn(), spawn());
                let (a, b) = (
                    bin_observed(&a.wait_with_output().unwrap()),
                    bin_observed(&b.wait_with_output().unwrap()),
                );
                let locked = |o: &Observed| matches!(&o.result, Err(e) if e.contains("lock held"));
                for o in [&a, &b] {
                    if o.panicked.is_some() || (o.result.is_err() && !locked(o)) {
                        return Observed::err(format!("{:?} {:?}", o.result, o.panicked));
                    }
                }
                if locked(&a) && locked(&b) {
                    return Observed::err("both runs were refused");
                }
                match equals_clean(&t.lands) {
                    Ok(()) => Observed::ok(format!(
                        "{}, {}; the files are a clean run's",
                        if locked(&a) {
                            "refused: lock held"
                        } else {
                            "succeeded"
                        },
                        if locked(&b) {
                            "refused: lock held"
                        } else {
                            "succeeded"
                        }
                    )),
                    Err(e) => Observed::err(e),
                }
            })
        }),
    ];
    let mut failures = run_cases(cases);
    // Most interrupts land mid-run (a run takes a few tens of milliseconds; a signal that comes
    // after its end still checks the rerun).
    let landed = LANDED.load(std::sync::atomic::Ordering::Relaxed);
    eprintln!("{landed} of 13 interrupts landed mid-run");
    if landed < 4 {
        failures.push(format!("only {landed} of 13 interrupts landed mid-run"));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
