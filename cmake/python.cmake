# The Python module `hinf` (python/): a pybind11 extension hinf._hinf over include/hinf/hinf.hpp plus a small
# pure-Python package (hinf/__init__.py: result files read with h5py). Built into BUILD/python/hinf/ (use it with
# PYTHONPATH=BUILD/python) and installed into HINF_PYTHON_INSTALL_DIR under the prefix. docs/python.md.
option(HINF_PYTHON "Build the Python module when pybind11 is installed (Debian pybind11-dev)" ON)
if(HINF_PYTHON AND NOT HINF_SANITIZE AND NOT HINF_FUZZ)
  set(PYBIND11_FINDPYTHON ON)
  # Debian's interpreter, which scripts/setup gives NumPy, h5py and pytest, unless one is named (-DPython_EXECUTABLE=)
  if(NOT Python_EXECUTABLE AND EXISTS /usr/bin/python3)
    set(Python_EXECUTABLE /usr/bin/python3 CACHE FILEPATH "The Python the module is built for")
  endif()
  find_package(pybind11 CONFIG QUIET)
endif()
if(HINF_PYTHON AND pybind11_FOUND AND NOT HINF_SANITIZE AND NOT HINF_FUZZ)
  pybind11_add_module(hinf_python MODULE ${CMAKE_CURRENT_SOURCE_DIR}/python/hinf_module.cpp)
  target_link_libraries(hinf_python PRIVATE hinf hinf_warnings)
  # pybind11 links the module with -flto; GCC then runs its link-time pass on one core and says so in a warning
  # ("using serial compilation"): -flto=auto lets it use the make's job slots or the cores
  target_link_options(hinf_python PRIVATE $<$<CXX_COMPILER_ID:GNU>:-flto=auto>)
  set_target_properties(hinf_python PROPERTIES OUTPUT_NAME _hinf
                        LIBRARY_OUTPUT_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR}/python/hinf)
  configure_file(${CMAKE_CURRENT_SOURCE_DIR}/python/hinf/__init__.py ${CMAKE_CURRENT_BINARY_DIR}/python/hinf/__init__.py COPYONLY)
  set(HINF_PYTHON_INSTALL_DIR lib/python${Python_VERSION_MAJOR}.${Python_VERSION_MINOR}/dist-packages
      CACHE STRING "Where the Python package hinf goes (under the prefix)")
  install(TARGETS hinf_python LIBRARY DESTINATION ${HINF_PYTHON_INSTALL_DIR}/hinf)
  install(FILES ${CMAKE_CURRENT_SOURCE_DIR}/python/hinf/__init__.py DESTINATION ${HINF_PYTHON_INSTALL_DIR}/hinf)
  # pytest over the module in the build tree, bit for bit against the `hinf` program (python/tests)
  if(HINF_BUILD_TESTS)
    add_test(NAME python_pytest
             COMMAND ${Python_EXECUTABLE} -m pytest -q -p no:cacheprovider ${CMAKE_CURRENT_SOURCE_DIR}/python/tests)
    set_tests_properties(python_pytest PROPERTIES TIMEOUT 300
      ENVIRONMENT "PYTHONPATH=${CMAKE_CURRENT_BINARY_DIR}/python;HINF_CLI=$<TARGET_FILE:hinf-cli>;HINF_SOURCE_DIR=${CMAKE_CURRENT_SOURCE_DIR};OMP_WAIT_POLICY=PASSIVE")
  endif()
  message(STATUS "hinf: Python module (pybind11 ${pybind11_VERSION}, Python ${Python_VERSION}) -> ${HINF_PYTHON_INSTALL_DIR}")
elseif(HINF_PYTHON AND NOT HINF_SANITIZE AND NOT HINF_FUZZ)
  message(STATUS "hinf: no Python module (install pybind11-dev python3-dev)")
endif()
