# ---- Per-ISA kernels (docs/design.md §ISA dispatch) ---------------------------------------------
# The hot kernels are compiled once per instruction set; core/linalg/isa.h picks one at run time.
# Each ISA's objects are compiled with hidden visibility inside their own namespace entry point
# (MARGLAB_ISA_NS), partially linked with their COMDAT groups dissolved (ld -r
# --force-group-allocation: otherwise the final link keeps one arbitrary copy of each Eigen
# instantiation across ISAs), and every symbol they define made local except the kernels() table
# (objcopy --keep-global-symbol: this also covers libstdc++'s templates, which keep default
# visibility whatever -fvisibility says). tools/scripts/check_isa_object.py then fails the build
# unless the object exports exactly its kernels() table and refers to no Eigen or weak symbol
# defined elsewhere: no code is shared between ISA copies.
# Sets MARGLAB_ISA_OBJECTS (one relocatable object per ISA, added to libmarglab) and
# MARGLAB_ISA_ONLY_SOURCES (compiled per ISA only, not into libmarglab itself).
#
# A sanitizer build (MARGLAB_SANITIZE, clang) has the SSE2 kernels only, not isolated: the
# isolation is GNU-specific (-fno-gnu-unique, the partial link) and the sanitizers' runtime
# references (__asan_*, the coverage sections) are exactly the undefined and shared symbols the
# check refuses. The sources are the same for every ISA; what the sanitizers check is the code.
# MARGLAB_ISA_SSE2_ONLY tells core/linalg/isa.cpp that the other ISAs are not built.
set(MARGLAB_ISA_ONLY_SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/estimator/linearization_kernels.cpp
                             ${CMAKE_CURRENT_SOURCE_DIR}/ba/landmark_system.cpp)
if(MARGLAB_SANITIZE)
  add_library(marglab_isa_sse2 OBJECT ${MARGLAB_ISA_ONLY_SOURCES})
  target_compile_definitions(marglab_isa_sse2 PRIVATE MARGLAB_ISA_NS=isa_sse2 MARGLAB_ISA_ENUM=kSse2
    $<$<BOOL:${MARGLAB_FLOAT}>:MARGLAB_WITH_FLOAT=1> MARGLAB_WITH_DOUBLE=1)
  target_include_directories(marglab_isa_sse2 PRIVATE ${CMAKE_SOURCE_DIR} ${CMAKE_BINARY_DIR}/generated)
  target_link_libraries(marglab_isa_sse2 PRIVATE Eigen3::Eigen fmt::fmt PkgConfig::TOMLPP
                                                 Threads::Threads Ceres::ceres)
  set(MARGLAB_ISA_OBJECTS $<TARGET_OBJECTS:marglab_isa_sse2>)
  set(MARGLAB_ISA_DEFINITIONS MARGLAB_ISA_SSE2_ONLY=1)
  return()
endif()
set(MARGLAB_ISA_DEFINITIONS "")
find_package(Python3 REQUIRED COMPONENTS Interpreter)
set(MARGLAB_ISA_KERNEL_SOURCES
    ${MARGLAB_ISA_ONLY_SOURCES}
    ${CMAKE_CURRENT_SOURCE_DIR}/estimator/window_landmark.cpp
    ${CMAKE_CURRENT_SOURCE_DIR}/ba/snavely_residual.cpp
    ${CMAKE_CURRENT_SOURCE_DIR}/linalg/landmark_block.cpp
    ${CMAKE_CURRENT_SOURCE_DIR}/linalg/landmark_block_implicit.cpp
    ${CMAKE_CURRENT_SOURCE_DIR}/linalg/landmark_block_sc.cpp
    ${CMAKE_CURRENT_SOURCE_DIR}/linalg/rcs_solve.cpp)
set(MARGLAB_ISA_FLAGS_sse2 "")
set(MARGLAB_ISA_ENUM_sse2 kSse2)
set(MARGLAB_ISA_FLAGS_avx2 -mavx2 -mfma -ffp-contract=fast)
set(MARGLAB_ISA_ENUM_avx2 kAvx2)
# -Wno-maybe-uninitialized: GCC 12's own avx512fintrin.h (the `__Y = __Y` idiom of
# _mm512_undefined_*) warns (a false positive) once Eigen's AVX-512 packets are inlined.
set(MARGLAB_ISA_FLAGS_avx512 -mavx512f -mavx512dq -mavx512vl -mavx512bw -mavx2 -mfma
    -ffp-contract=fast -Wno-maybe-uninitialized)
set(MARGLAB_ISA_ENUM_avx512 kAvx512)
set(MARGLAB_ISA_OBJECTS "")
foreach(isa sse2 avx2 avx512)
  set(target marglab_isa_${isa})
  add_library(${target} OBJECT ${MARGLAB_ISA_KERNEL_SOURCES})
  target_compile_options(${target} PRIVATE ${MARGLAB_ISA_FLAGS_${isa}} -fvisibility=hidden
                                           -fvisibility-inlines-hidden -fno-gnu-unique)
  # One Eigen ABI with the rest of the program (the library and Ceres, built for SSE2): matrices
  # cross between the ISA copies and the library, one side allocating what the other frees.
  # EIGEN_MAX_ALIGN_BYTES=16 keeps the objects' layout and the alignment Eigen assumes for their
  # data; EIGEN_MALLOC_ALREADY_ALIGNED=1 keeps the allocator plain malloc / free (with AVX Eigen
  # would switch to its own aligned allocator, whose blocks free() cannot release, and back);
  # its malloc and calloc calls are renamed below to marglab_isa_aligned_malloc / _calloc
  # (core/linalg/isa.cpp, 64-byte-aligned, released by free), so that Eigen's internal buffers,
  # which it loads with aligned AVX loads, are aligned as it assumes, and no result depends on
  # where the heap puts a block (GCC turns malloc + setZero into calloc).
  target_compile_definitions(${target} PRIVATE EIGEN_MAX_ALIGN_BYTES=16 EIGEN_MALLOC_ALREADY_ALIGNED=1
                                               MARGLAB_ISA_NS=isa_${isa}
                                               MARGLAB_ISA_ENUM=${MARGLAB_ISA_ENUM_${isa}}
    $<$<BOOL:${MARGLAB_FLOAT}>:MARGLAB_WITH_FLOAT=1> MARGLAB_WITH_DOUBLE=1)
  target_include_directories(${target} PRIVATE ${CMAKE_SOURCE_DIR} ${CMAKE_BINARY_DIR}/generated)
  target_link_libraries(${target} PRIVATE Eigen3::Eigen fmt::fmt PkgConfig::TOMLPP
                                          Threads::Threads Ceres::ceres)
  set(object ${CMAKE_CURRENT_BINARY_DIR}/marglab_isa_${isa}.o)
  string(LENGTH isa_${isa} namespace_length)
  set(entry _ZN7marglab${namespace_length}isa_${isa}7kernelsEv)  # marglab::isa_<isa>::kernels()
  add_custom_command(
    OUTPUT ${object}
    COMMAND ${CMAKE_LINKER} -r --force-group-allocation $<TARGET_OBJECTS:${target}>
            -o ${object}.partial
    COMMAND ${CMAKE_OBJCOPY} --keep-global-symbol=${entry}
            --redefine-sym malloc=marglab_isa_aligned_malloc
            --redefine-sym calloc=marglab_isa_aligned_calloc ${object}.partial ${object}
    COMMAND ${Python3_EXECUTABLE} ${CMAKE_SOURCE_DIR}/tools/scripts/check_isa_object.py
            ${object} isa_${isa}
    DEPENDS ${target} $<TARGET_OBJECTS:${target}>
            ${CMAKE_SOURCE_DIR}/tools/scripts/check_isa_object.py
    COMMENT "Isolating the ${isa} kernels"
    COMMAND_EXPAND_LISTS)
  list(APPEND MARGLAB_ISA_OBJECTS ${object})
endforeach()
set_source_files_properties(${MARGLAB_ISA_OBJECTS} PROPERTIES EXTERNAL_OBJECT TRUE GENERATED TRUE)
