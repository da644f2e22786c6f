# The include graph runs one way (core <- renderer, profiler <- scenarios <- reports <- apps), and the
# libraries that read files rather than drive a device link no Vulkan. Checked at configure time on the
# targets' link closure, so a dependency that breaks the layering fails the build with its path named.

# Sets ${out} to the chains "a -> b -> ..." from `target` to any of `forbidden` in its transitive link.
function(_hp_link_paths target forbidden chain visited_var out)
  set(found "")
  get_target_property(_libs ${target} LINK_LIBRARIES)
  get_target_property(_ilibs ${target} INTERFACE_LINK_LIBRARIES)
  foreach(lib IN LISTS _libs _ilibs)
    if(NOT lib OR lib MATCHES "^\\$<")
      continue()
    endif()
    if(lib IN_LIST forbidden)
      list(APPEND found "${chain} -> ${lib}")
      continue()
    endif()
    if(TARGET ${lib} AND NOT lib IN_LIST ${visited_var})
      list(APPEND ${visited_var} ${lib})
      _hp_link_paths(${lib} "${forbidden}" "${chain} -> ${lib}" ${visited_var} sub)
      list(APPEND found ${sub})
    endif()
  endforeach()
  set(${visited_var} ${${visited_var}} PARENT_SCOPE)
  set(${out} ${found} PARENT_SCOPE)
endfunction()

# FATAL_ERROR when `target` links (directly or through other targets) any of the listed targets.
function(hp_assert_not_linked target)
  set(visited "")
  _hp_link_paths(${target} "${ARGN}" "${target}" visited paths)
  if(paths)
    list(GET paths 0 first)
    message(FATAL_ERROR "layering: ${target} must not link ${ARGN}, but does: ${first}")
  endif()
endfunction()
