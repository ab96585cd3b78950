//! Preview rendering: a sphere covers the disc it should, back faces are coloured apart,
//! the bytes do not depend on the number of threads, and the PNG round-trips.

use sparc3d_render::{compare, render, Camera, CompareOptions, Image, Scene, BACK, BACKGROUND};
use sparcubes::shapes::{quad, sphere};

/// Share of pixels that are not background.
fn coverage(image: &Image) -> f64 {
    let covered = image
        .rgb
        .chunks(3)
        .filter(|p| *p != BACKGROUND.as_slice())
        .count();
    covered as f64 / (image.width as f64 * image.height as f64)
}

#[test]
fn sphere_renders_a_disc_of_the_expected_area() {
    let scene = Scene::new(&sphere([0.3, -0.2, 0.1], 1.0, 48));
    let half = 2.0;
    let expected = std::f64::consts::PI / (2.0 * half as f64).powi(2);
    for (az, el) in [(0.0, 0.0), (30.0, 30.0), (120.0, -45.0), (0.0, 90.0)] {
        let camera = Camera::orbit([0.3, -0.2, 0.1], half, az, el);
        let image = render(&scene, &camera, 256);
        let got = coverage(&image);
        assert!(
            (got - expected).abs() / expected < 0.03,
            "view ({az}, {el}): coverage {got:.4}, expected {expected:.4}"
        );
        // The middle of the disc faces the headlight: fully lit front colour, not red.
        let [r, g, b] = image.pixel(128, 128).unwrap();
        assert!(
            b > r && g > r,
            "centre pixel {:?} is not front-coloured",
            [r, g, b]
        );
        // Corners are background.
        assert_eq!(image.pixel(0, 0), Some(BACKGROUND));
        assert_eq!(image.pixel(255, 255), Some(BACKGROUND));
    }
}

#[test]
fn open_quad_seen_from_behind_shows_the_back_face_colour() {
    // Counter-clockwise seen from +z: its front faces +z.
    let scene = Scene::new(&quad(-1.0, -1.0, 1.0, 1.0, 0.0));
    let from_front = render(&scene, &Camera::orbit([0.0; 3], 2.0, 0.0, 0.0), 64);
    let from_behind = render(&scene, &Camera::orbit([0.0; 3], 2.0, 180.0, 0.0), 64);
    let front = from_front.pixel(32, 32).unwrap();
    let back = from_behind.pixel(32, 32).unwrap();
    assert_eq!(back, BACK, "seen from behind");
    assert_ne!(front, BACK, "seen from the front");
    assert!(
        front[2] > front[0],
        "front colour {front:?} should be blue-ish"
    );
    // Half the window is the quad (2 × 2 of 4 × 4) in both views.
    for image in [&from_front, &from_behind] {
        let c = coverage(image);
        assert!((c - 0.25).abs() < 0.02, "coverage {c}");
    }
}

#[test]
fn same_bytes_with_one_and_two_threads() {
    let mesh = sphere([0.0; 3], 1.0, 16);
    let open = quad(-1.5, -1.5, 1.5, 1.5, -0.5);
    let options = CompareOptions {
        views: 3,
        tile: 96,
        elevation_deg: 30.0,
    };
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| compare(&[&mesh, &open], &options))
    };
    let one = run(1);
    let two = run(2);
    assert_eq!(one.width, 3 * 96 + 2 * 2);
    assert_eq!(one.height, 2 * 96 + 2);
    assert!(one == two, "rendering depends on the number of threads");
}

#[test]
fn png_round_trips() {
    let image = compare(
        &[&sphere([0.0; 3], 1.0, 12)],
        &CompareOptions {
            views: 2,
            tile: 40,
            elevation_deg: 30.0,
        },
    );
    let bytes = image.encode_png().unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (image.width, image.height));
    assert_eq!(&buf[..info.buffer_size()], image.rgb.as_slice());
}

#[test]
fn empty_mesh_renders_background() {
    let scene = Scene::new(&sparcubes::TriMesh::default());
    let image = render(&scene, &Camera::orbit([0.0; 3], 1.0, 0.0, 0.0), 8);
    assert!(image.rgb.iter().all(|&b| b == 255));
}

/// FNV-1a (64-bit) of a picture's bytes: a short fingerprint to pin them by.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

#[test]
fn uncoloured_pictures_keep_their_bytes() {
    // The fingerprint of this picture as the renderer drew it before coloured previews
    // existed (commit 46e195c): a mesh drawn without colours must stay exactly as it was.
    let image = compare(
        &[
            &sphere([0.0; 3], 1.0, 16),
            &quad(-1.5, -1.5, 1.5, 1.5, -0.5),
        ],
        &CompareOptions {
            views: 3,
            tile: 64,
            elevation_deg: 30.0,
        },
    );
    assert_eq!(
        fnv1a(&image.rgb),
        0xc03f_7d2e_b318_b585,
        "{:#x}",
        fnv1a(&image.rgb)
    );
}
