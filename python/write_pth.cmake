# Build step of the Python module: writes watergs.pth, one line naming the
# build's python folder, into each site folder of SITE_DIRS ("|"-separated),
# replacing an earlier one atomically, as an editable install does. A folder
# it may not write is reported with the PYTHONPATH alternative, not an error.
#   cmake -DSITE_DIRS=a|b -DMODULE_DIR=<build>/python -P write_pth.cmake
string(REPLACE "|" ";" site_dirs "${SITE_DIRS}")
foreach(dir IN LISTS site_dirs)
  set(pth "${dir}/watergs.pth")
  if(EXISTS "${pth}")
    file(READ "${pth}" old)
    if(old STREQUAL "${MODULE_DIR}\n")
      message(STATUS "watergs: ${pth} -> ${MODULE_DIR} (import watergs from any folder)")
      continue()
    endif()
  endif()
  execute_process(COMMAND ${CMAKE_COMMAND} -E make_directory "${dir}"
    RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
  if(rc EQUAL 0)
    execute_process(COMMAND ${CMAKE_COMMAND} -E touch "${pth}.tmp"
      RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
  endif()
  if(NOT rc EQUAL 0)
    message(STATUS "watergs: cannot write ${pth}: import watergs with "
                   "PYTHONPATH=${MODULE_DIR}")
    continue()
  endif()
  file(WRITE "${pth}.tmp" "${MODULE_DIR}\n")
  file(RENAME "${pth}.tmp" "${pth}")
  message(STATUS "watergs: wrote ${pth} -> ${MODULE_DIR} (import watergs from any folder)")
endforeach()
