//! A small glTF writer for generated scenes (assets, tests). (Stub: being implemented.)
