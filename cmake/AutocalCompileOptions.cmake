# One function applies the language level and warnings to every autocal target.
function(autocal_target_defaults target)
  target_compile_features(${target} PUBLIC cxx_std_17)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
  if(AUTOCAL_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()
