//! Same seed, same world, byte for byte, whatever the thread count.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod sim_common;

use ibc_pipeline::sim::SimulatedWorld;
use sim_common::small;

fn files(world: &SimulatedWorld) -> Vec<(String, Vec<u8>)> {
    let dir = tempfile::tempdir().unwrap();
    let written = world.write(dir.path()).unwrap();
    [written.map, written.log, written.cameras, written.truth]
        .iter()
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(p).unwrap(),
            )
        })
        .collect()
}

#[test]
fn same_seed_gives_byte_identical_files() {
    for name in ["garage", "handheld-6dof"] {
        let s = small(name).with_seed(11);
        let a = files(&SimulatedWorld::simulate(&s).unwrap());
        let b = files(&SimulatedWorld::simulate(&s).unwrap());
        assert_eq!(a.len(), 4);
        for ((name_a, bytes_a), (_, bytes_b)) in a.iter().zip(&b) {
            assert!(!bytes_a.is_empty(), "{name_a} is empty");
            assert!(
                bytes_a == bytes_b,
                "{name}: {name_a} differs between two runs"
            );
        }
    }
}

#[test]
fn another_seed_gives_another_world() {
    let a = SimulatedWorld::simulate(&small("garage").with_seed(1)).unwrap();
    let b = SimulatedWorld::simulate(&small("garage").with_seed(2)).unwrap();
    assert_ne!(a.map.points, b.map.points);
    assert_ne!(
        a.log.frames[0].images[0].keypoints,
        b.log.frames[0].images[0].keypoints
    );
    // The trajectory and the rig do not depend on the seed; the world does.
    assert_eq!(a.truth.world_from_rig, b.truth.world_from_rig);
    assert_eq!(a.truth.rig_from_camera, b.truth.rig_from_camera);
}

#[test]
fn thread_count_does_not_change_the_world() {
    let s = small("street").with_seed(5);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| SimulatedWorld::simulate(&s).unwrap());
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap()
        .install(|| SimulatedWorld::simulate(&s).unwrap());
    assert!(one.map == three.map, "maps differ");
    assert!(one.log == three.log, "logs differ");
    assert_eq!(one.truth, three.truth);
    assert_eq!(one.log_point_ids, three.log_point_ids);
    assert_eq!(files(&one), files(&three));
}
