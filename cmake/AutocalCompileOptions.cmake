# One function applies the language level, warnings and (optionally) sanitizers to every
# autocal target.

# AUTOCAL_SANITIZE builds autocal's own targets with AddressSanitizer and
# UndefinedBehaviorSanitizer, plus the check for a floating-point value (NaN, inf, or out of
# range) converted to an integer type, which -fsanitize=undefined leaves out. Undefined
# behaviour aborts (no recovery), so any report fails the test that triggered it.
# Dependencies (Ceres, glog, ...) stay the uninstrumented Debian builds.
#
# EIGEN_MALLOC_ALREADY_ALIGNED=1: Eigen takes glibc's 16-byte aligned malloc as its aligned
# allocator only when __SANITIZE_ADDRESS__ is undefined; under ASan it switches to its own
# allocator, which over-allocates and stores the offset in front of the block. Debian's Ceres
# is compiled without ASan, so a matrix that Ceres allocates (GradientChecker's Jacobians)
# and autocal's code frees would go through different allocators and ASan reports a
# heap-buffer-overflow. Fixing the choice to glibc's malloc makes both sides agree.
option(AUTOCAL_SANITIZE "Build autocal's targets with ASan + UBSan (tests fail on a report)" OFF)
set(AUTOCAL_SANITIZE_FLAGS
    -fsanitize=address,undefined,float-cast-overflow -fno-sanitize-recover=all
    -fno-omit-frame-pointer)
set(AUTOCAL_SANITIZE_DEFINITIONS EIGEN_MALLOC_ALREADY_ALIGNED=1)

function(autocal_target_defaults target)
  target_compile_features(${target} PUBLIC cxx_std_17)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
  if(AUTOCAL_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(AUTOCAL_SANITIZE)
    target_compile_options(${target} PRIVATE ${AUTOCAL_SANITIZE_FLAGS})
    # GCC 12 at -O1 with the sanitizers reports std::regex's std::function members as
    # maybe-uninitialized (libstdc++'s regex compiler; a false positive, not seen at -O2 or
    # without the sanitizers) and -Werror made it stop the sanitize build.
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      target_compile_options(${target} PRIVATE -Wno-maybe-uninitialized)
    endif()
    target_compile_definitions(${target} PRIVATE ${AUTOCAL_SANITIZE_DEFINITIONS})
    target_link_options(${target} PRIVATE ${AUTOCAL_SANITIZE_FLAGS})
  endif()
endfunction()
