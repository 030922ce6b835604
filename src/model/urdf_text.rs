//! The URDF text before urdf-rs reads it: XML errors with their line, every number the model
//! uses checked where it is written (element, attribute, line), elements that only draw or
//! simulate (visuals, collisions, materials, Gazebo and transmission blocks) blanked so that
//! they can never fail a load, and the `velocity`/`effort` limits real URDFs omit filled in.
//!
//! urdf-rs reports a bad number as "invalid float literal" with no position, skips words it
//! cannot parse inside a vector (`xyz="1 a 2 3"` reads as 1 2 3) and takes `NaN` and `inf`;
//! the checks here run first so that none of that reaches the model.

use crate::error::{Error, Result};

/// Largest magnitude accepted for a URDF length, angle, mass, inertia, axis, damping or mimic
/// value. Larger finite values are not physical and overflow later products (a 1e308 m
/// offset squared is infinite), so they are refused here where the file can be named.
pub const MAX_URDF_MAGNITUDE: f64 = 1e9;

/// The joint types the URDF format defines (`spherical` is refused later with its own message).
const KNOWN_JOINT_TYPES: [&str; 7] = [
    "revolute",
    "continuous",
    "prismatic",
    "fixed",
    "floating",
    "planar",
    "spherical",
];

/// Children of `<robot>` and `<link>`/`<joint>` that the dynamics never reads.
const IGNORED: [(&str, &str); 7] = [
    ("link", "visual"),
    ("link", "collision"),
    ("joint", "calibration"),
    ("joint", "safety_controller"),
    ("robot", "material"),
    ("robot", "gazebo"),
    ("robot", "transmission"),
];

/// How many numbers an attribute holds and whether ±∞ is meaningful there (a missing limit).
struct Numeric {
    parent: &'static str,
    element: &'static str,
    attribute: &'static str,
    count: usize,
    infinite_ok: bool,
}

const fn num(parent: &'static str, element: &'static str, attribute: &'static str) -> Numeric {
    Numeric {
        parent,
        element,
        attribute,
        count: 1,
        infinite_ok: false,
    }
}

const NUMERIC: [Numeric; 22] = [
    Numeric {
        count: 3,
        ..num("inertial", "origin", "xyz")
    },
    Numeric {
        count: 3,
        ..num("inertial", "origin", "rpy")
    },
    Numeric {
        count: 4,
        ..num("inertial", "origin", "quat_xyzw")
    },
    num("inertial", "mass", "value"),
    num("inertial", "inertia", "ixx"),
    num("inertial", "inertia", "ixy"),
    num("inertial", "inertia", "ixz"),
    num("inertial", "inertia", "iyy"),
    num("inertial", "inertia", "iyz"),
    num("inertial", "inertia", "izz"),
    Numeric {
        count: 3,
        ..num("joint", "origin", "xyz")
    },
    Numeric {
        count: 3,
        ..num("joint", "origin", "rpy")
    },
    Numeric {
        count: 4,
        ..num("joint", "origin", "quat_xyzw")
    },
    Numeric {
        count: 3,
        ..num("joint", "axis", "xyz")
    },
    Numeric {
        infinite_ok: true,
        ..num("joint", "limit", "lower")
    },
    Numeric {
        infinite_ok: true,
        ..num("joint", "limit", "upper")
    },
    Numeric {
        infinite_ok: true,
        ..num("joint", "limit", "effort")
    },
    Numeric {
        infinite_ok: true,
        ..num("joint", "limit", "velocity")
    },
    num("joint", "dynamics", "damping"),
    num("joint", "dynamics", "friction"),
    num("joint", "mimic", "multiplier"),
    num("joint", "mimic", "offset"),
];

/// Check the text and return what urdf-rs should read (same length and lines as `text`
/// where nothing was inserted).
pub(super) fn prepare(text: &str, file: &str) -> Result<String> {
    let doc = roxmltree::Document::parse(text).map_err(|e| {
        let pos = e.pos();
        Error::Xml {
            file: file.to_string(),
            line: pos.row,
            column: pos.col,
            message: e.to_string(),
        }
    })?;
    let root = doc.root_element();
    if root.tag_name().name() != "robot" {
        return Err(Error::Urdf {
            file: file.to_string(),
            element: format!("<{}>", root.tag_name().name()),
            message: "the root element must be <robot>".to_string(),
        });
    }
    if !root.children().any(|n| n.has_tag_name("link")) {
        return Err(Error::Urdf {
            file: file.to_string(),
            element: "robot".to_string(),
            message: "the URDF has no links (an empty <robot>)".to_string(),
        });
    }
    let mut blank: Vec<std::ops::Range<usize>> = vec![];
    let mut inserts: Vec<(usize, String)> = vec![];
    for node in root.descendants().filter(|n| n.is_element()) {
        let tag = node.tag_name().name();
        let parent = node.parent_element().map(|p| p.tag_name().name());
        if IGNORED.iter().any(|(p, t)| Some(*p) == parent && *t == tag) {
            blank.push(node.range());
            continue;
        }
        if blank
            .last()
            .is_some_and(|r| r.contains(&node.range().start))
        {
            continue;
        }
        for spec in NUMERIC.iter() {
            if spec.element == tag
                && Some(spec.parent) == parent
                && let Some(attr) = node.attribute_node(spec.attribute)
            {
                check_numbers(&doc, file, node, &attr, spec)?;
            }
        }
        match tag {
            "joint" if parent == Some("robot") => check_joint_type(&doc, file, node)?,
            "limit" if parent == Some("joint") => {
                let mut extra = String::new();
                for attr in ["velocity", "effort"] {
                    if node.attribute(attr).is_none() {
                        extra.push_str(&format!(" {attr}=\"inf\""));
                    }
                }
                if !extra.is_empty() {
                    inserts.push((node.range().start + "<limit".len(), extra));
                }
            }
            _ => {}
        }
    }
    let mut out = blanked(text, &blank);
    for (pos, s) in inserts.into_iter().rev() {
        out.insert_str(pos, &s);
    }
    Ok(out)
}

/// `text` with every byte of the `ranges` but newlines replaced by spaces: the same length and
/// lines, so that byte positions found above stay valid.
fn blanked(text: &str, ranges: &[std::ops::Range<usize>]) -> String {
    let mut out = String::with_capacity(text.len());
    let mut last = 0;
    for r in ranges {
        out.push_str(&text[last..r.start]);
        for c in text[r.clone()].chars() {
            match c {
                '\n' => out.push('\n'),
                c => out.extend(std::iter::repeat_n(' ', c.len_utf8())),
            }
        }
        last = r.end;
    }
    out.push_str(&text[last..]);
    out
}

/// "link 'x'" or "joint 'y'": the named URDF element that holds `node`.
fn owner(node: roxmltree::Node) -> String {
    node.ancestors()
        .find(|a| a.has_tag_name("link") || a.has_tag_name("joint"))
        .map(|a| {
            format!(
                "{} '{}'",
                a.tag_name().name(),
                a.attribute("name").unwrap_or("?")
            )
        })
        .unwrap_or_else(|| "robot".to_string())
}

fn check_numbers(
    doc: &roxmltree::Document,
    file: &str,
    node: roxmltree::Node,
    attr: &roxmltree::Attribute,
    spec: &Numeric,
) -> Result<()> {
    let fail = |message: String| Error::UrdfValue {
        at: format!("{file}:{}", doc.text_pos_at(attr.range().start).row),
        element: format!(
            "<{}> of {}, {}=\"{}\"",
            spec.element,
            owner(node),
            spec.attribute,
            attr.value()
        ),
        message,
    };
    let words: Vec<&str> = attr.value().split_whitespace().collect();
    if words.len() != spec.count {
        return Err(fail(format!(
            "expected {} number{}, found {} word{}",
            spec.count,
            if spec.count == 1 { "" } else { "s" },
            words.len(),
            if words.len() == 1 { "" } else { "s" }
        )));
    }
    for w in words {
        let x: f64 = w
            .parse()
            .map_err(|_| fail(format!("'{w}' is not a number")))?;
        if x.is_nan() {
            return Err(fail("NaN is not a value".into()));
        }
        if x.is_infinite() && !spec.infinite_ok {
            return Err(fail(format!("{x} is not finite")));
        }
        if x.is_finite() && x.abs() > MAX_URDF_MAGNITUDE && !spec.infinite_ok {
            return Err(fail(format!(
                "{x:e} is beyond the accepted magnitude {MAX_URDF_MAGNITUDE:e} (SI units)"
            )));
        }
    }
    Ok(())
}

fn check_joint_type(doc: &roxmltree::Document, file: &str, joint: roxmltree::Node) -> Result<()> {
    let name = joint.attribute("name").unwrap_or("?");
    let ty = joint.attribute("type").unwrap_or("");
    if KNOWN_JOINT_TYPES.contains(&ty) {
        return Ok(());
    }
    Err(Error::Urdf {
        file: file.to_string(),
        element: format!(
            "joint '{name}' (line {})",
            doc.text_pos_at(joint.range().start).row
        ),
        message: format!(
            "unknown joint type '{ty}' (known: {})",
            KNOWN_JOINT_TYPES.join(", ")
        ),
    })
}
