//! A SCARA fit's verdict: the shared chi-square verdict (`crate::verdict`) with the SCARA's refit (in the file's
//! frame) and its own words for the causes.

use kinematics::ScaraFrame;

use super::{Identification, Measurement, ScaraGeometry, identify_in_frame};
use crate::verdict::{CauseWords, Fitted, Verdict, judge_fit};

const WORDS: CauseWords = CauseWords {
    swapped: "the x_mm and y_mm columns are swapped, or the file's frame is not the machine's (X-SCARA's frame swaps \
              them): with x and y exchanged the poses fit within the noise",
    general: &[
        "the motor angles are not the ones the machine commanded at these crosses (a pattern of another \
         configuration or another program, angles edited or rounded, rows out of order)",
        "the frame: x_mm, y_mm must be the printer's X and Y (the G-code's coordinates), the file's `frame` line \
         the machine's",
        "a cross measured from the wrong edge or corner, or the noise stated (--noise) smaller than the \
         measuring allows",
    ],
};

/// Judges `fit` of `data` (bed frame `frame`, started from `start`) at the stated `noise` (mm).
pub fn judge(
    data: &[Measurement],
    fit: &Identification,
    start: &ScaraGeometry,
    frame: ScaraFrame,
    noise: f64,
) -> Verdict {
    let fitted = Fitted {
        data,
        residuals: &fit.residuals,
        rms: fit.rms,
        parameters: 7,
    };
    let refit = |d: &[Measurement]| identify_in_frame(d, start, frame).ok().map(|f| f.residuals);
    judge_fit(&fitted, noise, &refit, &WORDS)
}
