// sdf_check: load a Gazebo world with libsdformat exactly as Gazebo does, run the checks of
// `gz sdf -k` (there is no gz CLI on Debian) and a few more, and print what Gazebo would
// see: every model's world pose and the lat/lon/alt Gazebo derives from it.
//
//   sdf_check WORLD [-m MODEL_DIR]...
//   sdf_check --robot MODEL     (a URDF or SDF robot, loaded as Gazebo loads a spawned model)
//
// `model://NAME` resolves against each MODEL_DIR, like GAZEBO_MODEL_PATH / GZ_SIM_RESOURCE_PATH.
// Checks: parse errors, warnings and unknown elements (all treated as errors), the
// `gz sdf -k` graph checks and sibling-name uniqueness, unresolved model:// URIs of includes,
// meshes and heightmaps, textures a COLLADA file names but that are missing, non-finite poses,
// non-positive shape sizes and mesh scales, and spherical coordinates out of range.
// Output (stdout, one record a line, space separated):
//   spherical LAT LON ELEVATION HEADING_DEG
//   model NAME X Y Z QW QX QY QZ LAT2 LON2 ALT2 LAT1 LON1 ALT1
//     LAT2.. = PositionTransform(LOCAL2 -> SPHERICAL): Gazebo Sim's NavSat;
//     LAT1.. = SphericalFromLocalPosition (LOCAL): Gazebo Classic 11's GpsSensor formula.
//   collision MODEL LINK NAME X Y Z QW QX QY QZ RADIUS LENGTH   (cylinders, world frame)
//   mesh MODEL URI PATH
//   Valid. | "error: ..." lines on stderr and exit status 1.
// Robot mode (--robot) runs the same graph checks on the model (a URDF converted by
// libsdformat's parser, fixed joints lumped as Gazebo lumps them; Gazebo's frame-id elements
// <ignition_frame_id>/<gz_frame_id> in a sensor are the only unknown elements allowed) and prints:
//   robot NAME CANONICAL_LINK
//   link NAME MASS
//   joint NAME TYPE PARENT CHILD AX AY AZ
//   sensor NAME TYPE LINK X Y Z QW QX QY QZ RATE TOPIC FRAME_ID   (pose in the model frame)
//   camera NAME HFOV WIDTH HEIGHT FORMAT NEAR FAR DEPTH_NEAR DEPTH_FAR NOISE_STDDEV
//   imu NAME LOCALIZATION GYRO_STDDEV_X Y Z ACCEL_STDDEV_X Y Z
//   navsat NAME HORIZONTAL_STDDEV VERTICAL_STDDEV
//   friction LINK COLLISION MU MU2
//   plugin FILENAME NAME
//   plugin_param NAME KEY VALUE        (each child of the plugin, in order)
#include <cmath>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <regex>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <vector>

#include <ignition/math/Pose3.hh>
#include <ignition/math/SphericalCoordinates.hh>
#include <sdf/sdf.hh>

namespace
{
int g_failures = 0;

void fail(const std::string &_msg)
{
  std::cerr << "error: " << _msg << "\n";
  ++g_failures;
}

bool isFile(const std::string &_path)
{
  struct stat st;
  return stat(_path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::string dirName(const std::string &_path)
{
  auto i = _path.find_last_of('/');
  return i == std::string::npos ? std::string(".") : _path.substr(0, i);
}

// Resolve a URI the way Gazebo's resource lookup does for local files.
std::string resolve(const std::string &_uri, const std::string &_fromFile,
                    const std::vector<std::string> &_modelDirs)
{
  const std::string scheme = "model://";
  if (_uri.rfind(scheme, 0) == 0)
  {
    const std::string rest = _uri.substr(scheme.size());
    for (const auto &dir : _modelDirs)
    {
      if (isFile(dir + "/" + rest))
        return dir + "/" + rest;
    }
    return "";
  }
  if (_uri.rfind("file://", 0) == 0)
    return isFile(_uri.substr(7)) ? _uri.substr(7) : "";
  if (!_uri.empty() && _uri[0] == '/')
    return isFile(_uri) ? _uri : "";
  const std::string rel = dirName(_fromFile) + "/" + _uri;
  return isFile(rel) ? rel : "";
}

void checkColladaTextures(const std::string &_dae)
{
  std::ifstream in(_dae);
  std::stringstream buf;
  buf << in.rdbuf();
  const std::string text = buf.str();
  // images live in <library_images>; scanning only that keeps a 10 MB terrain cheap
  const auto begin = text.find("<library_images");
  const auto end = text.find("</library_images>", begin == std::string::npos ? 0 : begin);
  if (begin == std::string::npos || end == std::string::npos)
    return;
  const std::string images = text.substr(begin, end - begin);
  static const std::regex image(R"(<image[^>]*>\s*<init_from>([^<]+)</init_from>)");
  for (auto it = std::sregex_iterator(images.begin(), images.end(), image);
       it != std::sregex_iterator(); ++it)
  {
    const std::string ref = (*it)[1].str();
    const std::string path = ref[0] == '/' ? ref : dirName(_dae) + "/" + ref;
    if (!isFile(path))
      fail("texture " + ref + " named by " + _dae + " does not exist");
  }
}

bool finite(const ignition::math::Pose3d &_p)
{
  return std::isfinite(_p.Pos().X()) && std::isfinite(_p.Pos().Y()) &&
         std::isfinite(_p.Pos().Z()) && std::isfinite(_p.Rot().W()) &&
         std::isfinite(_p.Rot().X()) && std::isfinite(_p.Rot().Y()) &&
         std::isfinite(_p.Rot().Z());
}

void printPose(const ignition::math::Pose3d &_p)
{
  std::cout << ' ' << _p.Pos().X() << ' ' << _p.Pos().Y() << ' ' << _p.Pos().Z() << ' '
            << _p.Rot().W() << ' ' << _p.Rot().X() << ' ' << _p.Rot().Y() << ' '
            << _p.Rot().Z();
}

void checkGeometry(const sdf::Geometry *_geom, const std::string &_where,
                   const std::string &_model, const std::vector<std::string> &_modelDirs)
{
  if (_geom == nullptr)
  {
    fail(_where + " has no geometry");
    return;
  }
  if (const auto *mesh = _geom->MeshShape())
  {
    const auto s = mesh->Scale();
    if (!(s.X() > 0 && s.Y() > 0 && s.Z() > 0 && std::isfinite(s.X()) &&
          std::isfinite(s.Y()) && std::isfinite(s.Z())))
      fail(_where + " has a non-positive mesh scale");
    const std::string path = resolve(mesh->Uri(), mesh->FilePath(), _modelDirs);
    if (path.empty())
    {
      fail(_where + ": mesh " + mesh->Uri() + " does not resolve");
      return;
    }
    std::cout << "mesh " << _model << ' ' << mesh->Uri() << ' ' << path << "\n";
    if (path.size() > 4 && path.compare(path.size() - 4, 4, ".dae") == 0)
      checkColladaTextures(path);
  }
  else if (const auto *cyl = _geom->CylinderShape())
  {
    if (!(cyl->Radius() > 0 && cyl->Length() > 0))
      fail(_where + " has a cylinder of non-positive size");
  }
  else if (const auto *box = _geom->BoxShape())
  {
    const auto s = box->Size();
    if (!(s.X() > 0 && s.Y() > 0 && s.Z() > 0))
      fail(_where + " has a box of non-positive size");
  }
  else if (const auto *hm = _geom->HeightmapShape())
  {
    const auto s = hm->Size();
    if (!(s.X() > 0 && s.Y() > 0 && s.Z() >= 0))
      fail(_where + " has a heightmap of non-positive size");
    const std::string path = resolve(hm->Uri(), hm->FilePath(), _modelDirs);
    if (path.empty())
      fail(_where + ": heightmap " + hm->Uri() + " does not resolve");
  }
}

ignition::math::Pose3d resolved(const sdf::SemanticPose &_sp, const std::string &_where)
{
  ignition::math::Pose3d pose;
  const sdf::Errors errs = _sp.Resolve(pose);
  for (const auto &e : errs)
    fail(_where + ": " + e.Message());
  if (!finite(pose))
    fail(_where + " has a non-finite pose");
  return pose;
}

// Gazebo Sim reads a sensor's frame id from these elements, which SDFormat 1.9 does not define.
bool allowedUnknown(const std::string &_msg)
{
  for (const char *name : {"ignition_frame_id", "gz_frame_id"})
  {
    const std::string want = std::string("XML Element[") + name + "], child of element[sensor]";
    if (_msg.find(want) != std::string::npos)
      return true;
  }
  return false;
}

std::string childText(const sdf::ElementPtr &_el, const std::string &_name)
{
  if (!_el || !_el->HasElement(_name))
    return "-";
  const sdf::ElementPtr child = _el->FindElement(_name);
  const sdf::ParamPtr value = child ? child->GetValue() : nullptr;
  return value ? value->GetAsString() : "-";
}

double noiseStd(const sdf::Noise &_noise)
{
  return _noise.Type() == sdf::NoiseType::NONE ? 0.0 : _noise.StdDev();
}

int robotMain(const std::string &_file)
{
  sdf::ParserConfig config;
  config.SetWarningsPolicy(sdf::EnforcementPolicy::ERR);
  config.SetUnrecognizedElementsPolicy(sdf::EnforcementPolicy::ERR);
  sdf::Root root;
  const sdf::Errors errors = root.Load(_file, config);
  int hard = 0;
  for (const auto &e : errors)
  {
    if (allowedUnknown(e.Message()))
      continue;
    fail(e.Message());
    ++hard;
  }
  if (hard > 0)
    return 1;
  if (!sdf::checkCanonicalLinkNames(&root))
    fail("canonical link names");
  if (!sdf::checkJointParentChildLinkNames(&root))
    fail("joint parent/child link names");
  if (!sdf::checkFrameAttachedToGraph(&root))
    fail("frame attached-to graph");
  if (!sdf::checkPoseRelativeToGraph(&root))
    fail("pose relative-to graph");
  if (!sdf::recursiveSiblingUniqueNames(root.Element()))
    fail("sibling elements share a name");
  const sdf::Model *model = root.Model();
  if (model == nullptr)
  {
    fail("the file holds no model");
    return 1;
  }
  if (model->Static())
    fail("the robot is static");
  const sdf::Link *canonical = model->CanonicalLink();
  std::cout << "robot " << model->Name() << ' '
            << (canonical ? canonical->Name() : std::string("-")) << "\n";
  for (uint64_t l = 0; l < model->LinkCount(); ++l)
  {
    const sdf::Link *link = model->LinkByIndex(l);
    const std::string lw = "link " + link->Name();
    const double mass = link->Inertial().MassMatrix().Mass();
    if (!(mass > 0))
      fail(lw + " has no mass");
    std::cout << "link " << link->Name() << ' ' << mass << "\n";
    ignition::math::Pose3d X_ML;
    for (const auto &e : link->SemanticPose().Resolve(X_ML, "__model__"))
      fail(lw + ": " + e.Message());
    for (uint64_t c = 0; c < link->CollisionCount(); ++c)
    {
      const sdf::Collision *col = link->CollisionByIndex(c);
      checkGeometry(col->Geom(), lw + " collision " + col->Name(), model->Name(), {});
      const sdf::ElementPtr el = col->Element();
      sdf::ElementPtr ode;
      if (el && el->HasElement("surface"))
      {
        const sdf::ElementPtr surface = el->FindElement("surface");
        if (surface->HasElement("friction"))
        {
          const sdf::ElementPtr friction = surface->FindElement("friction");
          if (friction->HasElement("ode"))
            ode = friction->FindElement("ode");
        }
      }
      std::cout << "friction " << link->Name() << ' ' << col->Name() << ' '
                << childText(ode, "mu") << ' ' << childText(ode, "mu2") << "\n";
    }
    for (uint64_t s = 0; s < link->SensorCount(); ++s)
    {
      const sdf::Sensor *sensor = link->SensorByIndex(s);
      const std::string sw = lw + " sensor " + sensor->Name();
      ignition::math::Pose3d X_MS;
      for (const auto &e : sensor->SemanticPose().Resolve(X_MS, "__model__"))
        fail(sw + ": " + e.Message());
      if (!finite(X_MS))
        fail(sw + " has a non-finite pose");
      const sdf::ElementPtr el = sensor->Element();
      std::string frameId = childText(el, "ignition_frame_id");
      const std::string gzFrameId = childText(el, "gz_frame_id");
      if (frameId != gzFrameId)
        fail(sw + ": ignition_frame_id and gz_frame_id differ");
      if (!(sensor->UpdateRate() > 0))
        fail(sw + " has no update rate");
      if (sensor->Topic().empty() || sensor->Topic() == "__default__")
        fail(sw + " has no topic");
      std::cout << "sensor " << sensor->Name() << ' ' << sensor->TypeStr() << ' '
                << link->Name();
      printPose(X_MS);
      std::cout << ' ' << sensor->UpdateRate() << ' ' << sensor->Topic() << ' ' << frameId
                << "\n";
      if (const sdf::Camera *cam = sensor->CameraSensor())
      {
        std::cout << "camera " << sensor->Name() << ' ' << cam->HorizontalFov().Radian() << ' '
                  << cam->ImageWidth() << ' ' << cam->ImageHeight() << ' '
                  << cam->PixelFormatStr() << ' ' << cam->NearClip() << ' ' << cam->FarClip()
                  << ' ' << cam->DepthNearClip() << ' ' << cam->DepthFarClip() << ' '
                  << noiseStd(cam->ImageNoise()) << "\n";
      }
      if (const sdf::Imu *imu = sensor->ImuSensor())
      {
        std::cout << "imu " << sensor->Name() << ' ' << imu->Localization() << ' '
                  << noiseStd(imu->AngularVelocityXNoise()) << ' '
                  << noiseStd(imu->AngularVelocityYNoise()) << ' '
                  << noiseStd(imu->AngularVelocityZNoise()) << ' '
                  << noiseStd(imu->LinearAccelerationXNoise()) << ' '
                  << noiseStd(imu->LinearAccelerationYNoise()) << ' '
                  << noiseStd(imu->LinearAccelerationZNoise()) << "\n";
      }
      if (const sdf::NavSat *navsat = sensor->NavSatSensor())
      {
        std::cout << "navsat " << sensor->Name() << ' '
                  << noiseStd(navsat->HorizontalPositionNoise()) << ' '
                  << noiseStd(navsat->VerticalPositionNoise()) << "\n";
      }
    }
  }
  for (uint64_t j = 0; j < model->JointCount(); ++j)
  {
    const sdf::Joint *joint = model->JointByIndex(j);
    const sdf::JointAxis *axis = joint->Axis(0);
    const auto xyz = axis ? axis->Xyz() : ignition::math::Vector3d::Zero;
    std::string type;
    switch (joint->Type())
    {
      case sdf::JointType::CONTINUOUS: type = "continuous"; break;
      case sdf::JointType::REVOLUTE: type = "revolute"; break;
      case sdf::JointType::FIXED: type = "fixed"; break;
      default: type = "other"; break;
    }
    std::cout << "joint " << joint->Name() << ' ' << type << ' ' << joint->ParentLinkName()
              << ' ' << joint->ChildLinkName() << ' ' << xyz.X() << ' ' << xyz.Y() << ' '
              << xyz.Z() << "\n";
  }
  for (sdf::ElementPtr plugin = model->Element()->HasElement("plugin")
                                    ? model->Element()->GetElement("plugin")
                                    : nullptr;
       plugin; plugin = plugin->GetNextElement("plugin"))
  {
    const std::string name = plugin->Get<std::string>("name");
    std::cout << "plugin " << plugin->Get<std::string>("filename") << ' ' << name << "\n";
    for (sdf::ElementPtr child = plugin->GetFirstElement(); child;
         child = child->GetNextElement())
    {
      const sdf::ParamPtr value = child->GetValue();
      std::cout << "plugin_param " << name << ' ' << child->GetName() << ' '
                << (value ? value->GetAsString() : std::string("-")) << "\n";
    }
  }
  if (g_failures > 0)
    return 1;
  std::cout << "Valid.\n";
  return 0;
}
}  // namespace

int main(int argc, char **argv)
{
  if (argc == 3 && std::string(argv[1]) == "--robot")
  {
    if (!isFile(argv[2]))
    {
      std::cerr << "usage: sdf_check --robot MODEL (the file must exist)\n";
      return 2;
    }
    std::cout << std::setprecision(15);
    return robotMain(argv[2]);
  }
  std::string world;
  std::vector<std::string> modelDirs;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    if (arg == "-m" && i + 1 < argc)
      modelDirs.emplace_back(argv[++i]);
    else if (world.empty())
      world = arg;
    else
    {
      std::cerr << "usage: sdf_check WORLD [-m MODEL_DIR]... | --robot MODEL\n";
      return 2;
    }
  }
  if (world.empty() || !isFile(world))
  {
    std::cerr << "usage: sdf_check WORLD [-m MODEL_DIR]... (world file must exist)\n";
    return 2;
  }
  std::cout << std::setprecision(15);

  sdf::ParserConfig config;
  for (const auto &dir : modelDirs)
    config.AddURIPath("model://", dir);
  config.SetWarningsPolicy(sdf::EnforcementPolicy::ERR);
  config.SetUnrecognizedElementsPolicy(sdf::EnforcementPolicy::ERR);

  sdf::Root root;
  const sdf::Errors errors = root.Load(world, config);
  for (const auto &e : errors)
    fail(e.Message());
  if (!errors.empty())
    return 1;

  // The checks `gz sdf -k` runs after loading.
  if (!sdf::checkCanonicalLinkNames(&root))
    fail("canonical link names");
  if (!sdf::checkJointParentChildLinkNames(&root))
    fail("joint parent/child link names");
  if (!sdf::checkFrameAttachedToGraph(&root))
    fail("frame attached-to graph");
  if (!sdf::checkPoseRelativeToGraph(&root))
    fail("pose relative-to graph");
  if (!sdf::recursiveSiblingUniqueNames(root.Element()))
    fail("sibling elements share a name");
  {
    sdf::SDFPtr raw(new sdf::SDF());
    sdf::init(raw);
    sdf::Errors readErrors;
    if (!sdf::readFile(world, config, raw, readErrors))
      fail("SDF parsing the xml failed");
  }

  if (root.WorldCount() != 1)
  {
    fail("expected exactly one world");
    return 1;
  }
  const sdf::World *w = root.WorldByIndex(0);
  const ignition::math::SphericalCoordinates *sc = w->SphericalCoordinates();
  if (sc == nullptr)
  {
    fail("world has no spherical_coordinates");
    return 1;
  }
  const double lat0 = sc->LatitudeReference().Degree();
  const double lon0 = sc->LongitudeReference().Degree();
  if (!(std::abs(lat0) <= 90 && std::abs(lon0) <= 180 && std::isfinite(sc->ElevationReference())))
    fail("spherical coordinates out of range");
  std::cout << "spherical " << lat0 << ' ' << lon0 << ' ' << sc->ElevationReference() << ' '
            << sc->HeadingOffset().Degree() << "\n";

  for (uint64_t m = 0; m < w->ModelCount(); ++m)
  {
    const sdf::Model *model = w->ModelByIndex(m);
    const std::string name = model->Name();
    const ignition::math::Pose3d X_WM = resolved(model->SemanticPose(), "model " + name);
    const auto p2 = sc->PositionTransform(
        X_WM.Pos(), ignition::math::SphericalCoordinates::LOCAL2,
        ignition::math::SphericalCoordinates::SPHERICAL);
    const auto p1 = sc->SphericalFromLocalPosition(X_WM.Pos());
    std::cout << "model " << name;
    printPose(X_WM);
    std::cout << ' ' << p2.X() * 180.0 / M_PI << ' ' << p2.Y() * 180.0 / M_PI << ' ' << p2.Z()
              << ' ' << p1.X() << ' ' << p1.Y() << ' ' << p1.Z() << "\n";
    if (!model->Static() && model->LinkCount() > 0)
      fail("model " + name + " is not static (field models must not move)");
    for (uint64_t l = 0; l < model->LinkCount(); ++l)
    {
      const sdf::Link *link = model->LinkByIndex(l);
      const std::string lw = "model " + name + " link " + link->Name();
      const ignition::math::Pose3d X_WL = X_WM * resolved(link->SemanticPose(), lw);
      for (uint64_t v = 0; v < link->VisualCount(); ++v)
      {
        const sdf::Visual *vis = link->VisualByIndex(v);
        resolved(vis->SemanticPose(), lw + " visual " + vis->Name());
        checkGeometry(vis->Geom(), lw + " visual " + vis->Name(), name, modelDirs);
      }
      for (uint64_t c = 0; c < link->CollisionCount(); ++c)
      {
        const sdf::Collision *col = link->CollisionByIndex(c);
        const std::string cw = lw + " collision " + col->Name();
        const ignition::math::Pose3d X_WC = X_WL * resolved(col->SemanticPose(), cw);
        checkGeometry(col->Geom(), cw, name, modelDirs);
        if (const auto *cyl = col->Geom() ? col->Geom()->CylinderShape() : nullptr)
        {
          std::cout << "collision " << name << ' ' << link->Name() << ' ' << col->Name();
          printPose(X_WC);
          std::cout << ' ' << cyl->Radius() << ' ' << cyl->Length() << "\n";
        }
      }
    }
  }
  if (g_failures > 0)
    return 1;
  std::cout << "Valid.\n";
  return 0;
}
