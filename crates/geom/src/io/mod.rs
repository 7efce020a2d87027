//! File formats. TODO(helper): PLY, OBJ, OFF, STL, XYZ readers/writers.
