#include "test_paths.h"

namespace marglab::test {

const char* cliPath() { return MARGLAB_CLI; }
const char* binaryDir() { return MARGLAB_BINARY_DIR; }

}  // namespace marglab::test
