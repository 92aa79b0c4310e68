from aioadept import MoveTo
from aioadept.protocol import encode_command, parse_ack, Status


def test_paper_command_line_encodes_verbatim():
    call = MoveTo([-80, -481, 112.5, 180, 90, 180]).calls()[0]
    assert encode_command("eae86869", call) == (
        b"eae86869:move_to:-80.000,-481.000,112.500,180.000,90.000,180.000\r\n")


def test_paper_ack_line_parses():
    ack = parse_ack(b"eae86869:done:2492.516,2492.539:480.014,-0.038,709.975,0.000,179.995,0.004")
    assert ack.status is Status.DONE and ack.t_done_s == 2492.539 and ack.pose.y == -0.038
