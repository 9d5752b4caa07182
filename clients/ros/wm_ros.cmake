# Whether the ROS 1 bridge's tests are registered (included by clients/ros and tests/ros). ROS 1 is never needed
# by the core build: WM_BUILD_ROS=AUTO (the default) turns them on when /usr/bin/roscore is there and the
# Python that Debian's ROS modules live in imports rospy, rosbag and tf2_ros; ON registers them anyway (they
# exit 77, skipped, without ROS); OFF leaves them out. `scripts/setup.sh ros` installs ROS 1.
set(WM_BUILD_ROS AUTO CACHE STRING "Register the ROS 1 bridge tests: AUTO (when ROS 1 is installed), ON or OFF")
set_property(CACHE WM_BUILD_ROS PROPERTY STRINGS AUTO ON OFF)
# Debian's ROS modules are in the system interpreter's dist-packages, which a python3 earlier on PATH
# (pyenv, a venv) does not see.
set(WM_ROS_PYTHON /usr/bin/python3 CACHE FILEPATH "Python interpreter that imports Debian's rospy")

if(WM_BUILD_ROS STREQUAL "AUTO")
  set(WM_ROS_ENABLED OFF)
  if(EXISTS /usr/bin/roscore AND EXISTS "${WM_ROS_PYTHON}")
    execute_process(COMMAND "${WM_ROS_PYTHON}" -c "import rospy, rosbag, tf2_ros"
                    RESULT_VARIABLE _wm_ros_import OUTPUT_QUIET ERROR_QUIET)
    if(_wm_ros_import EQUAL 0)
      set(WM_ROS_ENABLED ON)
    endif()
  endif()
elseif(WM_BUILD_ROS)
  set(WM_ROS_ENABLED ON)
else()
  set(WM_ROS_ENABLED OFF)
endif()
