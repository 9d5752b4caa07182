#pragma once

#include <string>
#include <vector>

#include "apriori/export/layer_lines.h"

namespace wm::apriori {

/// Writes layers of polylines as an ASCII DXF R12 (AC1009) drawing in metres ($INSUNITS 6, $MEASUREMENT 1):
/// a LAYER table with one layer per input layer (in input order, with its colour, CONTINUOUS), and in ENTITIES a
/// LINE for each 2-point polyline and a POLYLINE/VERTEX/SEQEND for longer ones (flag 1 "closed" when the last
/// point repeats the first, which is then not written twice). R12 is the dialect every CAD and GIS tool reads
/// (AutoCAD, LibreCAD, QCAD, ezdxf, GDAL/QGIS). Numbers are written in the shortest form that reads back to the
/// same double, so read_dxf(write_dxf(x)) gives x exactly.
/// Layer names are made valid for R12: characters other than letters, digits, '_', '-' and '$' become '_', and
/// names are cut to 31 characters (layers whose names then coincide are written as one).
/// @throw std::invalid_argument (message starts "write_dxf:") for an empty layer name, a polyline with fewer than
///        2 points, a non-finite coordinate, a colour outside 1..255, or ids that are neither empty nor one per
///        polyline.
std::string write_dxf(const std::vector<LayerLines>& layers);

/// The R12-safe form of a layer name used by write_dxf.
std::string dxf_layer_name(const std::string& layer);

}  // namespace wm::apriori
