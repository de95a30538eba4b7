//! `penmesh synth`: write a generated stroke to a file.

use std::path::PathBuf;

use clap::Args;

use crate::commands::args::GeneratorArgs;
use crate::io;

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// The shape: figure8, semicircles, chromosome, leaf or scribble.
    pub shape: penmesh::Shape,
    /// Where to write the stroke; `.json` writes JSON, anything else CSV.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub generator: GeneratorArgs,
}

pub fn run(args: &SynthArgs) -> anyhow::Result<()> {
    let params = args.generator.params(args.shape, 0);
    let stroke = penmesh::generate_stroke(&params).map_err(|e| anyhow::anyhow!("{e}"))?;
    let is_json = args.out.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
    let strokes = [stroke];
    let text = if is_json { penmesh::write_json(&strokes) } else { penmesh::write_csv(&strokes) };
    io::write_file(&args.out, text)?;
    let stroke = &strokes[0];
    let duration = stroke.samples().last().map_or(0.0, |s| s.t);
    println!(
        "{}: {} {} samples, {:.0} px long, {:.0} ms",
        args.out.display(),
        args.shape,
        stroke.len(),
        stroke.length(),
        duration
    );
    Ok(())
}
