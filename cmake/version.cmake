# Writes version.h with the current git revision; run at every build so that results files
# record the revision that produced them. configure_file leaves the file untouched when nothing
# changed, so nothing recompiles needlessly.
execute_process(
  COMMAND git rev-parse --short=12 HEAD
  WORKING_DIRECTORY ${SOURCE_DIR}
  OUTPUT_VARIABLE MARGLAB_GIT_SHA
  OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
execute_process(
  COMMAND git status --porcelain --untracked-files=no
  WORKING_DIRECTORY ${SOURCE_DIR}
  OUTPUT_VARIABLE MARGLAB_GIT_DIRTY
  OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
if(NOT MARGLAB_GIT_SHA)
  set(MARGLAB_GIT_SHA "unknown")
elseif(MARGLAB_GIT_DIRTY)
  set(MARGLAB_GIT_SHA "${MARGLAB_GIT_SHA}-dirty")
endif()
set(PROJECT_VERSION ${VERSION})
configure_file(${SOURCE_DIR}/core/common/version.h.in ${OUTPUT} @ONLY)
