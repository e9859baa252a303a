// The top layer of the fixture.
#pragma once
