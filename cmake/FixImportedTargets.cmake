# Debian 12 ships two imported targets whose include paths do not exist:
#  - OpenImageIO lists /usr/include/opencv4 (OIIO was built with OpenCV, libopenimageio-dev does not pull it in);
#  - OpenColorIO's config sits in /usr/share/cmake, so its computed prefix is wrong and it lists /include.
# envkit uses neither path, so drop include directories that do not exist (the real ones are under /usr/include).
function(envkit_drop_missing_includes target)
  if(NOT TARGET ${target})
    return()
  endif()
  get_target_property(dirs ${target} INTERFACE_INCLUDE_DIRECTORIES)
  if(NOT dirs)
    return()
  endif()
  set(kept)
  foreach(dir ${dirs})
    if(EXISTS "${dir}")
      list(APPEND kept "${dir}")
    endif()
  endforeach()
  set_target_properties(${target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${kept}")
endfunction()
