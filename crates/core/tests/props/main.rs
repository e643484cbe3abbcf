//! Property tests over generated inputs, in one test binary: adaptation keeps a valid
//! mesh for any point set ([`adapt`]), and reconstruction returns curves or a typed
//! error for anything finite, independent of the data's units ([`reconstruct`]), and
//! no scan's curve crosses space its beams saw through ([`seen`]).

mod adapt;
mod reconstruct;
mod seen;
