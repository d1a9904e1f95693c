#include "core/common/source_dir.h"

namespace marglab {

const char* sourceDir() { return MARGLAB_SOURCE_DIR; }

}  // namespace marglab
