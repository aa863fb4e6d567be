// Four drones fly a lane each, north and back, at once (tests/operator/test_amend.py):
// the operator amends the later legs of some of them while they fly.
package FourLanes

var Drone1 Quadcopter
var Drone2 Quadcopter
var Drone3 Quadcopter
var Drone4 Quadcopter

func PAR_Lanes() {
	SEQ_Lane1()
	SEQ_Lane2()
	SEQ_Lane3()
	SEQ_Lane4()
}

func SEQ_Lane1() {
	Drone1.Arm()
	Drone1.Takeoff(2)
	Drone1.FlyByX(12)
	Drone1.FlyByX(-12)
	Drone1.Land()
}

func SEQ_Lane2() {
	Drone2.Arm()
	Drone2.Takeoff(2)
	Drone2.FlyByX(12)
	Drone2.FlyByX(-12)
	Drone2.Land()
}

func SEQ_Lane3() {
	Drone3.Arm()
	Drone3.Takeoff(2)
	Drone3.FlyByX(12)
	Drone3.FlyByX(-12)
	Drone3.Land()
}

func SEQ_Lane4() {
	Drone4.Arm()
	Drone4.Takeoff(2)
	Drone4.FlyByX(12)
	Drone4.FlyByX(-12)
	Drone4.Land()
}
