#pragma once
// The marglab source tree this binary was built from (fixed at configure time). Shipped data,
// experiments, paper values and the Python scripts are found under it. Kept behind a function in
// one translation unit so that the path is compiled into one object only: every other object is
// the same for every checkout, which lets a compiler cache share them between checkouts.

namespace marglab {

const char* sourceDir();

}  // namespace marglab
