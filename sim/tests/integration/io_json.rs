//! calib.json, prior.json / truth.json and result.json.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, missing_docs)]

use std::path::Path;
use vtsm_core::geom::Pose;
use vtsm_sim::io::json::{self, PoseJson, ResultFile};

const CALIB: &str = r#"{
  "width": 640,
  "height": 480,
  "fx": 500.5,
  "fy": 501.0,
  "cx": 319.5,
  "cy": 239.5,
  "baseline_m": 0.4
}"#;

fn p() -> &'static Path {
    Path::new("calib.json")
}

/// Verifies: VTSM-CLI-006
#[test]
fn valid_calib_gives_the_stereo_rig() {
    let c = json::parse_calib(CALIB.as_bytes(), p()).unwrap();
    let rig = c.rig().unwrap();
    assert_eq!((rig.cam().width(), rig.cam().height()), (640, 480));
    assert_eq!(
        (
            rig.cam().fx(),
            rig.cam().fy(),
            rig.cam().cx(),
            rig.cam().cy()
        ),
        (500.5, 501.0, 319.5, 239.5)
    );
    assert_eq!(rig.baseline_m(), 0.4);
    // written and read back unchanged
    assert_eq!(
        json::parse_calib(json::calib_text(&c).as_bytes(), p()).unwrap(),
        c
    );
}

/// Verifies: VTSM-CLI-006, VTSM-CLI-008
#[test]
fn bad_calib_values_are_rejected_with_field_and_line() {
    let cases: &[(&str, &str, usize, &str)] = &[
        ("\"fx\": 500.5", "\"fx\": -1", 4, "fx"),
        ("\"fy\": 501.0", "\"fy\": 0", 5, "fy"),
        ("\"width\": 640", "\"width\": 0", 2, "width"),
        ("\"height\": 480", "\"height\": 100000", 3, "height"),
        (
            "\"baseline_m\": 0.4",
            "\"baseline_m\": 0.0",
            8,
            "baseline_m",
        ),
        ("\"cx\": 319.5", "\"cx\": 1e300", 6, "cx"),
        ("\"fx\": 500.5", "\"fx\": NaN", 4, "invalid JSON"),
        ("\"fx\": 500.5", "\"fx\": 1e999", 4, "invalid JSON"),
        ("\"fx\": 500.5", "\"focal\": 500.5", 4, "unknown field"),
        ("\"width\": 640", "\"width\": -640", 2, "invalid JSON"),
        (
            "\"baseline_m\": 0.4\n}",
            "\"baseline_m\": 0.4\n",
            9,
            "invalid JSON",
        ),
    ];
    for (from, to, line, what) in cases {
        let text = CALIB.replace(from, to);
        let e = json::parse_calib(text.as_bytes(), p()).unwrap_err();
        assert_eq!(e.file.as_deref(), Some(p()));
        assert_eq!(e.line, Some(*line), "{to}: {e}");
        assert!(e.msg.contains(what), "{to}: {e}");
        assert_eq!(e.to_string().lines().count(), 1);
    }
    // Finite but outside the core camera's range: named, with a short number.
    for (from, to, line, field) in [
        ("\"fx\": 500.5", "\"fx\": 1e300", 4, "`fx`"),
        ("\"fy\": 501.0", "\"fy\": 2e6", 5, "`fy`"),
        ("\"fx\": 500.5", "\"fx\": 1e-60", 4, "`fx`"),
        ("\"cy\": 239.5", "\"cy\": -1e5", 7, "`cy`"),
        (
            "\"baseline_m\": 0.4",
            "\"baseline_m\": 1e300",
            8,
            "`baseline_m`",
        ),
    ] {
        let text = CALIB.replace(from, to);
        let e = json::parse_calib(text.as_bytes(), p()).unwrap_err();
        let shown = e.to_string();
        assert_eq!(e.line, Some(line), "{to}: {shown}");
        assert!(
            shown.starts_with("calib.json:") && shown.contains(field),
            "{shown}"
        );
        assert!(shown.len() < 160, "{shown}");
        assert_eq!(shown.lines().count(), 1);
    }
    let missing = CALIB.replace("  \"cy\": 239.5,\n", "");
    let e = json::parse_calib(missing.as_bytes(), p()).unwrap_err();
    assert!(e.msg.contains("missing field `cy`"), "{e}");
}

fn pose_text(t: [f64; 3], q: [f64; 4]) -> String {
    format!(
        "{{\"world_from_left\": {{\n  \"t\": [{}, {}, {}],\n  \"q\": [{}, {}, {}, {}]\n}}}}",
        t[0], t[1], t[2], q[0], q[1], q[2], q[3]
    )
}

/// Verifies: VTSM-CLI-006
#[test]
fn prior_pose_reads_and_rejects_non_unit_quaternions() {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let pose = json::parse_pose(
        pose_text([1.0, -2.0, 0.5], [h, 0.0, 0.0, h]).as_bytes(),
        p(),
    )
    .unwrap();
    assert_eq!(pose.t(), [1.0, -2.0, 0.5]);
    // 90° about z maps x to y
    let v = pose.transform_vector(&vtsm_core::geom::Vec3::new(1.0, 0.0, 0.0));
    assert!((v.x).abs() < 1e-6 && (v.y - 1.0).abs() < 1e-6);
    // Within tolerance is accepted and renormalised.
    let near =
        json::parse_pose(pose_text([0.0; 3], [1.0005, 0.0, 0.0, 0.0]).as_bytes(), p()).unwrap();
    let q = near.q();
    assert!((q.iter().map(|v| v * v).sum::<f32>() - 1.0).abs() < 1e-6);
    for q in [[1.01, 0.0, 0.0, 0.0], [0.0; 4], [0.5, 0.5, 0.5, 0.4]] {
        let e = json::parse_pose(pose_text([0.0; 3], q).as_bytes(), p()).unwrap_err();
        assert_eq!(e.line, Some(3), "{e}");
        assert!(e.msg.contains("norm"), "{e}");
    }
    let e = json::parse_pose(
        pose_text([1e300, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]).as_bytes(),
        p(),
    )
    .unwrap_err();
    assert_eq!(
        (e.line, e.msg.contains("not finite")),
        (Some(2), true),
        "{e}"
    );
    let e = json::parse_pose(
        b"{\"world_from_left\": {\"t\": [0, 0], \"q\": [1, 0, 0, 0]}}",
        p(),
    )
    .unwrap_err();
    assert!(e.msg.contains("invalid JSON"), "{e}");
    // Round trip through the writer.
    let back = json::parse_pose(json::pose_file_text(&pose).as_bytes(), p()).unwrap();
    assert_eq!(back.t(), pose.t());
    assert_eq!(back.q(), pose.q());
}

/// Verifies: VTSM-CLI-007
#[test]
fn result_file_has_the_design_fields() {
    let stats = json::WorkStats {
        renders: 12,
        ..json::WorkStats::default()
    };
    let r = ResultFile {
        status: "ok".into(),
        failure: None,
        world_from_left: Some(PoseJson::from_pose(&Pose::identity())),
        inliers: 87,
        iterations: 5,
        stats,
        covariance: Some(
            (0..36)
                .map(|i| if i % 7 == 0 { 1e-6 } else { 0.0 })
                .collect(),
        ),
        verified: json::Verified {
            repeat_solve: true,
            recheck_map: false,
        },
        prior_uncertainty: Some(json::UncertaintyJson {
            t_m: 0.5,
            r_deg: 1.5,
        }),
    };
    let text = json::result_text(&r);
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["status"], "ok");
    assert!(v["failure"].is_null());
    assert_eq!(
        v["world_from_left"]["q"],
        serde_json::json!([1.0, 0.0, 0.0, 0.0])
    );
    assert_eq!(
        v["world_from_left"]["t"],
        serde_json::json!([0.0, 0.0, 0.0])
    );
    assert_eq!(v["inliers"], 87);
    assert_eq!(v["iterations"], 5);
    assert_eq!(v["stats"]["renders"], 12);
    assert_eq!(v["stats"].as_object().unwrap().len(), 33);
    assert_eq!(
        v["stats"]["ncc_matches_by_variant"]
            .as_array()
            .unwrap()
            .len(),
        6
    );
    assert_eq!(v["covariance"].as_array().unwrap().len(), 36);
    assert_eq!(v["covariance"][7], 1e-6);
    assert_eq!(v["verified"]["repeat_solve"], true);
    assert_eq!(v["verified"]["recheck_map"], false);
    assert_eq!(
        v["prior_uncertainty"],
        serde_json::json!({"t_m": 0.5, "r_deg": 1.5})
    );
    assert_eq!(json::parse_result(text.as_bytes(), p()).unwrap(), r);
    // A result written before `verified` existed reads as "no check ran".
    let old = text.replace(
        ",\n  \"verified\": {\n    \"repeat_solve\": true,\n    \"recheck_map\": false\n  }",
        "",
    );
    assert!(!old.contains("verified"), "{old}");
    let back = json::parse_result(old.as_bytes(), p()).unwrap();
    assert_eq!(back.verified, json::Verified::default());
}

/// A prior with `uncertainty` on its own lines: `t_m` on line 5, `r_deg` on 6.
fn prior_with(t_m: &str, r_deg: &str) -> String {
    format!(
        "{{\"world_from_left\": {{\n  \"t\": [1.0, 2.0, 0.5],\n  \"q\": [1.0, 0.0, 0.0, 0.0]}},\n \"uncertainty\": {{\n  \"t_m\": {t_m},\n  \"r_deg\": {r_deg}}}}}"
    )
}

fn prior_path() -> &'static Path {
    Path::new("prior.json")
}

/// Verifies: VTSM-CLI-041
#[test]
fn prior_uncertainty_reads_as_written_and_absent_means_none() {
    let f = json::parse_prior(prior_with("0.5", "1.5").as_bytes(), prior_path()).unwrap();
    assert_eq!(
        f.uncertainty,
        Some(json::UncertaintyJson {
            t_m: 0.5,
            r_deg: 1.5
        })
    );
    assert_eq!(f.world_from_left.t, [1.0, 2.0, 0.5]);
    let u = f.uncertainty.unwrap().core();
    assert_eq!((u.t_m, u.r_deg), (0.5, 1.5));
    // The echo of the core's f32 is the number as written.
    for (t, r) in [(0.35, 2.25), (0.2, 1.5), (2.0, 20.0), (0.001, 0.01)] {
        let u = json::UncertaintyJson { t_m: t, r_deg: r };
        assert_eq!(json::UncertaintyJson::from_core(&u.core()), u);
    }
    // The largest accepted values are the core's caps.
    let top = json::parse_prior(prior_with("2", "20").as_bytes(), prior_path()).unwrap();
    assert_eq!(top.uncertainty.unwrap().core().validate(), Ok(()));
    // Absent (or null): no stated uncertainty; the pose reads the same.
    let plain = pose_text([1.0, 2.0, 0.5], [1.0, 0.0, 0.0, 0.0]);
    let f = json::parse_prior(plain.as_bytes(), prior_path()).unwrap();
    assert_eq!(f.uncertainty, None);
    let null = r#"{"world_from_left": {"t": [1, 2, 0.5], "q": [1, 0, 0, 0]}, "uncertainty": null}"#;
    assert_eq!(
        json::parse_prior(null.as_bytes(), prior_path())
            .unwrap()
            .uncertainty,
        None
    );
    // The pose-only readers accept a prior with an uncertainty.
    let pose = json::parse_pose(prior_with("0.5", "1.5").as_bytes(), prior_path()).unwrap();
    assert_eq!(pose.t(), [1.0, 2.0, 0.5]);
    // The writer leaves it out when there is none.
    assert!(!json::pose_file_text(&pose).contains("uncertainty"));
}

/// Every bad `uncertainty` is refused with one line naming the file, the line
/// and the field; out-of-range values carry `HAL_PRIOR_INVALID`.
///
/// Verifies: VTSM-CLI-041, VTSM-CLI-008
#[test]
fn bad_prior_uncertainty_is_refused_with_the_exact_error() {
    let out_of_range = |line: usize, key: &str, shown: &str| {
        let (unit, max) = if key == "t_m" {
            ("m", "2")
        } else {
            ("deg", "20")
        };
        format!(
            "prior.json:{line}: `uncertainty.{key}`: {shown} {unit} is outside the accepted range (0, {max}] {unit}"
        )
    };
    let cases: Vec<(String, String, Option<vtsm_core::FailureCode>)> = vec![
        // Zero, negative, huge, too small for f32, just above the cap.
        (prior_with("0", "1.5"), out_of_range(5, "t_m", "0"), Some(HPI)),
        (prior_with("-0.4", "1.5"), out_of_range(5, "t_m", "-0.4"), Some(HPI)),
        (prior_with("1e300", "1.5"), out_of_range(5, "t_m", "1e300"), Some(HPI)),
        (prior_with("1e-60", "1.5"), out_of_range(5, "t_m", "1e-60"), Some(HPI)),
        (prior_with("2.5", "1.5"), out_of_range(5, "t_m", "2.5"), Some(HPI)),
        (prior_with("0.5", "0"), out_of_range(6, "r_deg", "0"), Some(HPI)),
        (prior_with("0.5", "-1.5"), out_of_range(6, "r_deg", "-1.5"), Some(HPI)),
        (prior_with("0.5", "30"), out_of_range(6, "r_deg", "30"), Some(HPI)),
        // Not numbers JSON can hold.
        (
            prior_with("NaN", "1.5"),
            "prior.json:5: invalid JSON: expected value".into(),
            None,
        ),
        (
            prior_with("0.5", "1e999"),
            "prior.json:6: invalid JSON: number out of range".into(),
            None,
        ),
        // Wrong types.
        (
            prior_with("\"0.5\"", "1.5"),
            "prior.json:5: invalid JSON: invalid type: string \"0.5\", expected f64".into(),
            None,
        ),
        (
            prior_with("[0.5]", "1.5"),
            "prior.json:5: invalid JSON: invalid type: sequence, expected f64".into(),
            None,
        ),
        (
            r#"{"world_from_left": {"t": [1, 2, 0.5], "q": [1, 0, 0, 0]}, "uncertainty": 0.5}"#
                .into(),
            "prior.json:1: invalid JSON: invalid type: floating point `0.5`, expected struct UncertaintyJson".into(),
            None,
        ),
        // Unknown and missing keys.
        (
            prior_with("0.5", "1.5, \"z_m\": 0.1"),
            "prior.json:6: invalid JSON: unknown field `z_m`, expected `t_m` or `r_deg`".into(),
            None,
        ),
        (
            r#"{"world_from_left": {"t": [1, 2, 0.5], "q": [1, 0, 0, 0]}, "uncertainty": {"t_m": 0.5}}"#
                .into(),
            "prior.json:1: invalid JSON: missing field `r_deg`".into(),
            None,
        ),
        (
            r#"{"world_from_left": {"t": [1, 2, 0.5], "q": [1, 0, 0, 0]}, "uncertainty_m": 0.5}"#
                .into(),
            "prior.json:1: invalid JSON: unknown field `uncertainty_m`, expected one of `world_from_left`, `uncertainty`, `sun`".into(),
            None,
        ),
    ];
    for (text, want, code) in cases {
        let e = json::parse_prior(text.as_bytes(), prior_path()).unwrap_err();
        assert_eq!(e.to_string(), want, "{text}");
        assert_eq!(e.code, code, "{text}");
        // The pose-only reader (truth.json) refuses the same file the same way.
        let e2 = json::parse_pose_json(text.as_bytes(), prior_path()).unwrap_err();
        assert_eq!(e2, e);
    }
}

const HPI: vtsm_core::FailureCode = vtsm_core::FailureCode::HalPriorInvalid;

/// A `result.json` written before `prior_uncertainty` existed still reads.
///
/// Verifies: VTSM-CLI-007
#[test]
fn result_without_prior_uncertainty_reads_as_none() {
    let text = r#"{"status":"failed","failure":"RELOC_NO_EVIDENCE","world_from_left":null,"inliers":0,"iterations":0,"stats":{}}"#;
    let r = json::parse_result(text.as_bytes(), p()).unwrap();
    assert_eq!((r.prior_uncertainty, r.covariance), (None, None));
}

/// A prior's capture-time `sun` reads as written, absent means none, and a
/// sun out of range or with an unknown field is refused with the prior's
/// code and the line of the `sun` key.
#[test]
fn prior_sun_reads_as_written_and_bad_suns_are_refused() {
    let with = |sun: &str| {
        format!(
            "{{\"world_from_left\": {{\"t\": [1.0, 2.0, 0.5], \"q\": [1.0, 0.0, 0.0, 0.0]}},\n \"sun\": {sun}}}"
        )
    };
    let f = json::parse_prior(
        with("{\"azimuth_deg\": 231.0, \"elevation_deg\": 16.5}").as_bytes(),
        Path::new("prior.json"),
    )
    .unwrap();
    let s = f.sun.unwrap();
    assert_eq!((s.azimuth_deg, s.elevation_deg), (231.0, 16.5));
    let none = json::parse_prior(
        pose_text([1.0, 2.0, 0.5], [1.0, 0.0, 0.0, 0.0]).as_bytes(),
        Path::new("prior.json"),
    )
    .unwrap();
    assert_eq!(none.sun, None);
    for bad in [
        "{\"azimuth_deg\": 231.0, \"elevation_deg\": 0.5}",
        "{\"azimuth_deg\": 231.0, \"elevation_deg\": -4.0}",
        "{\"azimuth_deg\": 231.0, \"elevation_deg\": 95.0}",
    ] {
        let e = json::parse_prior(with(bad).as_bytes(), Path::new("prior.json")).unwrap_err();
        assert_eq!(
            e.code,
            Some(vtsm_core::FailureCode::HalPriorInvalid),
            "{bad}: {e}"
        );
        assert!(e.to_string().contains("prior.json:2"), "{bad}: {e}");
    }
    for bad in [
        "{\"azimuth_deg\": 231.0}",
        "{\"azimuth_deg\": 231.0, \"elevation_deg\": 20.0, \"hours\": 15}",
        "\"231,20\"",
    ] {
        assert!(
            json::parse_prior(with(bad).as_bytes(), Path::new("prior.json")).is_err(),
            "{bad} was taken"
        );
    }
}
