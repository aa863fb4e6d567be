// Two drones fly a lane each, north and back, at once (tests/fleetops/test_rollout_by_content.py):
// an edit inserts a statement into Drone1's lane only.
package Lanes

var Drone1 Quadcopter
var Drone2 Quadcopter

func PAR_Lanes() {
	SEQ_Lane1()
	SEQ_Lane2()
}

func SEQ_Lane1() {
	Drone1.Arm()
	Drone1.Takeoff(2)
	Drone1.FlyByX(4)
	Drone1.FlyByX(-4)
	Drone1.Land()
}

func SEQ_Lane2() {
	Drone2.Arm()
	Drone2.Takeoff(2)
	Drone2.FlyByX(4)
	Drone2.FlyByX(-4)
	Drone2.Land()
}
