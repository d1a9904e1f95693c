#pragma once
// Paths fixed when the tests are configured: the marglab binary under test and the build folder.
// In one translation unit (test_paths.cpp) so that every other test object is the same for every
// checkout and a compiler cache can share it; marglab::sourceDir() gives the source tree.

namespace marglab::test {

const char* cliPath();
const char* binaryDir();

}  // namespace marglab::test
