# spacewarp_configure_target(<target>): warnings, sanitizers and the C++ standard for one
# of the project's own targets. Applied per target; no global flags.
function(spacewarp_configure_target target)
  target_compile_features(${target} PUBLIC cxx_std_20)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
  # <spacewarp/...> includes, also for targets that compile sources without linking core.
  target_include_directories(${target} PRIVATE ${SPACEWARP_BUILD_INCLUDE_DIR})
  if(SPACEWARP_WARNINGS_AS_ERRORS)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(SPACEWARP_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer
                                             -fno-sanitize-recover=undefined)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
  endif()
endfunction()
