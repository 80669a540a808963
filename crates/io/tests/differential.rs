//! Our safetensors reader against the official one (Hugging Face's `safetensors` crate) on mutants of valid
//! files: both must accept the same files and read the same values from them; where they differ, ours must be
//! refusing a dtype it says it does not read. This is why the hand-written reader stays (README,
//! "Reliability"): it is as strict as the official one, its errors say what is wrong (`truncated: header says
//! 96 bytes of tensors, file has 86` where the crate says `incomplete metadata, file not fully covered`), and
//! its writer is deterministic (the crate's orders metadata through a `HashMap`).

use pganeus_io::*;
use std::collections::BTreeMap;
use std::path::Path;
use testkit::fuzz::Mutator;

const P: &str = "mutant";
const CASES: usize = 20_000;

fn data(name: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)).unwrap()
}

/// What the official crate reads: metadata and (name, dtype, shape, bytes) of every tensor.
type Official = (
    BTreeMap<String, String>,
    BTreeMap<String, (String, Vec<usize>, Vec<u8>)>,
);

fn official_safetensors(b: &[u8]) -> Option<Official> {
    let (_, meta) = safetensors::SafeTensors::read_metadata(b).ok()?;
    let st = safetensors::SafeTensors::deserialize(b).ok()?;
    let metadata = meta.metadata().clone().unwrap_or_default().into_iter().collect();
    let tensors = st
        .tensors()
        .into_iter()
        .map(|(name, v)| {
            (
                name,
                (format!("{:?}", v.dtype()), v.shape().to_vec(), v.data().to_vec()),
            )
        })
        .collect();
    Some((metadata, tensors))
}

fn ours_as_official(st: &SafeTensors) -> Official {
    let tensors = st
        .tensors
        .iter()
        .map(|(name, t)| {
            let mut bytes = Vec::new();
            t.data.extend_le_bytes(&mut bytes);
            (name.clone(), (t.data.dtype().to_string(), t.shape.clone(), bytes))
        })
        .collect();
    (st.metadata.clone(), tensors)
}

#[test]
fn safetensors_reader_agrees_with_the_official_crate() {
    let seeds = [data("official.safetensors"), {
        let mut st = SafeTensors::new();
        st.metadata.insert("format".into(), "pganeus".into());
        st.insert("w", Tensor::f32(vec![2, 2], vec![1.0, -2.0, 3.5, 0.0]));
        st.insert("step", Tensor::new(vec![], TensorData::I64(vec![7])));
        safetensors_bytes(&st)
    }];
    let mut m = Mutator::new(17);
    let (mut accepted, mut refused_unsupported) = (0, 0);
    let mut disagreements = Vec::new();
    for k in 0..CASES {
        let b = m.mutate(&seeds[k % seeds.len()]);
        let ours = read_safetensors_bytes(&b, Path::new(P));
        match (ours, official_safetensors(&b)) {
            (Ok(st), Some(theirs)) => {
                accepted += 1;
                if ours_as_official(&st) != theirs {
                    disagreements.push(format!("case {k}: both read it, with different values"));
                }
            }
            (Err(_), None) => {}
            (Err(e), Some((_, tensors))) => {
                // Dtypes we do not read (BF16, I8, ...) are refused by name; anything else is a disagreement.
                let unsupported = tensors
                    .values()
                    .any(|(d, _, _)| !["F32", "F64", "U8", "I64", "U32"].contains(&d.as_str()));
                if unsupported && e.to_string().contains("is not supported") {
                    refused_unsupported += 1;
                } else {
                    disagreements.push(format!("case {k}: ours refuses ({e}), the crate reads it"));
                }
            }
            (Ok(_), None) => disagreements.push(format!("case {k}: ours reads it, the crate refuses")),
        }
    }
    println!("safetensors: {CASES} mutants, {accepted} read alike by both, {refused_unsupported} refused for a dtype we do not read, {} disagreements", disagreements.len());
    assert!(
        disagreements.is_empty(),
        "{:?}",
        &disagreements[..disagreements.len().min(10)]
    );
    assert!(accepted > 0);
}
